"""Issue 29's fleet on real autopilots: two ArduCopter (or PX4) SITL binaries (their own
instances, ports and system ids), each flying a world of its own on one episode through its
physics bridge, one fleet companion flying both over their own links in their dialect. Run
only where the binaries are (ARDUPILOT_SITL / PX4_SITL name them); CI has none."""

import os
from pathlib import Path

import pytest

from missions.fleet_trial import fly_fleet_trial
from sim.gridworld import GridConfig

pytestmark = pytest.mark.slow


@pytest.mark.skipif(not os.environ.get("PX4_SITL"), reason="PX4_SITL (the px4 SITL binary) is not set")
def test_two_px4s_find_every_target_apart_and_land(tmp_path: Path) -> None:
    """The same on two PX4 SITL binaries in lockstep with our bridges, as fast as the machine
    allows (speedup 0): 21 s here."""
    r = fly_fleet_trial(tmp_path, 2, GridConfig(width=8, height=8, n_targets=3), seed=0, speedup=0, plot=False,
                        autopilot="px4")
    assert r["outcome"] == 0 and r["truly_found"] == 3 and r["separation_refused"] == 0 and not r["lost"], r
    assert r["min_true_distance_3d_m"] >= 2.0 and r["armed_after"] == [False, False], r
    assert max(r["height_after_m"]) < 0.3, "both disarmed on the ground"


@pytest.mark.skipif(not os.environ.get("ARDUPILOT_SITL"), reason="ARDUPILOT_SITL (the arducopter binary) is not set")
def test_two_arducopters_find_every_target_apart_and_land(tmp_path: Path) -> None:
    """8 x 8 / 3, seed 0, at 10x (35 s here, loaded: ArduPilot waits for each physics reply, so
    a slow bridge slows the simulated clock, it does not break the lockstep)."""
    r = fly_fleet_trial(tmp_path, 2, GridConfig(width=8, height=8, n_targets=3), seed=0, speedup=10, plot=False,
                        autopilot="ardupilot")
    assert r["outcome"] == 0 and r["truly_found"] == 3 and r["believed_found"] == 3, r
    assert r["separation_refused"] == 0 and not r["lost"], r
    level = r["min_true_separation_same_height_m"]  # None: never within 1 m of one height in the air
    assert (level is None or level >= 2.0) and r["min_true_distance_3d_m"] >= 2.0, r
    assert r["armed_after"] == [False, False] and max(r["height_after_m"]) < 0.3, "both disarmed on the ground"


def test_a_fleet_of_real_autopilots_refuses_what_it_does_not_fly(tmp_path: Path) -> None:
    for kw in ({"autopilot": "inav"}, {"autopilot": "ardupilot", "cut": (1, 2)}):
        with pytest.raises(ValueError, match="inav|cut"):
            fly_fleet_trial(tmp_path, 2, GridConfig(width=8, height=8, n_targets=3), plot=False, **kw)


def test_sitl_refuses_by_name_the_fleets_it_does_not_run(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from missions.cli import app

    out = ["--field-out", str(tmp_path / "f.json"), "-i", "27"]
    for args, words in ((["--autopilot", "ardupilot", "--count", "2"], "--one-field"),
                        (["--count", "2", "--one-field", "--levels", "2"], "one height")):
        r = CliRunner().invoke(app, ["sitl", *out, *args])
        assert r.exit_code == 2 and words in " ".join(r.output.replace("│", " ").split()), (args, r.output)
    assert not list(tmp_path.iterdir())
