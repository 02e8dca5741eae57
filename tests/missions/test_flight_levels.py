"""A real flight with altitude levels (docs/altitude.md): the companion climbs and descends as
the levels' planner asks, the vehicle settles at each level's height over home, the frames are
read at the height flown, and the flight flies the grid world's search on the same episode."""

from pathlib import Path

import pytest

from missions.fieldfile import FieldSpec, read_field, write_field
from missions.flight import fly_search
from sim.gridworld import DetectionTable, GridConfig, level_height_m
from sim.gridworld.geodesy import HomePosition


def test_the_field_file_carries_the_levels_and_their_table(tmp_path: Path) -> None:
    """`sitl --levels` tells `run --field` to fly them, with the table the grid flies."""
    table = DetectionTable.perfect(3)
    grid = GridConfig(width=12, height=8, n_targets=4, levels=2, detection=table)
    origin = HomePosition(51.45, -2.59, 30.0)
    write_field(tmp_path / "levels.json", FieldSpec(origin, grid), 0)
    assert read_field(tmp_path / "levels.json").grid == grid
    write_field(tmp_path / "one.json", FieldSpec(origin, GridConfig()), 0)
    assert "levels" not in (tmp_path / "one.json").read_text(), "one level: the file as before"
    assert read_field(tmp_path / "one.json").grid == GridConfig()


@pytest.mark.slow
def test_a_search_with_three_levels_flies_the_grid_worlds(tmp_path: Path) -> None:
    grid = GridConfig(width=10, height=10, n_targets=3, levels=3)  # the measured detection table
    r = fly_search(tmp_path, seed=1, speedup=20.0, grid=grid, free_ports=True, plot=False)
    assert r["error"] is None, r["error"]
    assert r["truly_found"] == r["believed_found"] == 3
    assert r["moves"] == r["grid_moves"], (r["moves"], r["grid_moves"])
    levels, heights = r["levels_flown"], r["camera_height_m"]
    assert len(levels) == len(heights) == r["moves"] + 1
    assert max(levels) == 2, "a 10 x 10 field is searched from level 2 at most (its footprint fits twice)"
    assert levels[0] == levels[-1] == 1, "it starts at the paper's height and finds at level 1"
    for lv, h in zip(levels, heights, strict=True):  # the EKF/baro height flown, settled near the level's
        assert abs(h - (level_height_m(lv) - 0.06)) < 0.4, (lv, h)
    assert r["schedule_slips"] == 0 and r["late_frames"] == 0
    # a decision every 4 simulated s, climbs and descents included (and a centring on a target at level 1)
    assert 4.0 * r["moves"] <= r["search_s"] <= 4.0 * (r["moves"] + 2 * 3)


def test_flight_table_levels_refuse_only_what_is_not_flown(tmp_path: Path) -> None:
    """A real autopilot flies --levels (the test above); what is still refused names its option:
    the video camera, --baseline-levels beside a real autopilot or a polygon field."""
    from typer.testing import CliRunner

    from missions.cli import app

    runner = CliRunner()
    for extra, hint in ((["--camera", "video"], "--levels"),
                        (["--autopilot", "ardupilot", "--baseline-levels", "1"], "--baseline-levels"),
                        (["--field", "examples/fields/out/farm_barn/field.json", "--baseline-levels", "1"],
                         "--baseline-levels")):
        r = runner.invoke(app, ["flight-table", "--levels", "2", *extra, "--out", str(tmp_path)])
        assert r.exit_code == 2 and hint in r.output, (extra, r.output)
