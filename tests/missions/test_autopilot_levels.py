"""Altitude levels on the real autopilots (issue 27): ArduCopter and PX4 climb and descend the
levels over our world (sim.bridges), each on its own height estimate. Skipped where
ARDUPILOT_SITL / PX4_SITL are not set.

(In its own file, ahead of test_field_flight: a real ArduCopter flight after a polygon field's
flight in the same process timed out waiting for its EKF_STATUS_REPORT, on the tree before
these changes too; each passes alone.)"""

import os
from pathlib import Path

import pytest

from missions.flight import fly_search
from sim.gridworld import GridConfig, level_height_m


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", [
    pytest.param("ardupilot", marks=pytest.mark.skipif(not os.environ.get("ARDUPILOT_SITL"),
                                                       reason="ARDUPILOT_SITL (the arducopter binary) is not set")),
    pytest.param("px4", marks=pytest.mark.skipif(not os.environ.get("PX4_SITL"),
                                                 reason="PX4_SITL (the px4 SITL binary) is not set")),
])
def test_a_real_autopilot_climbs_and_descends_the_levels(tmp_path: Path, autopilot: str) -> None:
    """ArduCopter (GUIDED) and PX4 (OFFBOARD) fly the levels as our vehicle does: each level's
    height over home is the setpoint's z in the autopilot's local frame, the height settled and
    the frames read at it come from the autopilot's own estimate (ArduCopter's EKF3, PX4's
    baro-held EKF2), and the search is the grid world's on the same episode."""
    grid = GridConfig(width=10, height=10, n_targets=3, levels=3)
    r = fly_search(tmp_path, seed=1, speedup=5.0, grid=grid, autopilot=autopilot, plot=False)  # as flight-table flies them
    assert r["error"] is None, r["error"]
    assert r["truly_found"] == r["believed_found"] == 3
    assert r["moves"] == r["grid_moves"], (r["moves"], r["grid_moves"])
    levels, heights = r["levels_flown"], r["camera_height_m"]
    assert 2 in levels and levels[0] == levels[-1] == 1, levels  # a climb and a descent
    for lv, h in zip(levels, heights, strict=True):
        assert abs(h - (level_height_m(lv) - 0.06)) < 0.4, (lv, h)
    assert r["schedule_slips"] == 0

