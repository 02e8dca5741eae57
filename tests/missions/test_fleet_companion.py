"""Issue 29's fleet flight for real: `uavsearch sitl --count N --one-field` and one
`uavsearch run --fleet` companion flying every vehicle over its own MAVLink link, with a
pymavlink ground station per vehicle; a vehicle whose link is cut mid-search is taken out and
lands on its own failsafe while the others finish; a SIGTERM lands every vehicle."""

import json
import os
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from flight_procs import GroundStation, Lines, stop_process, uavsearch, until
from pymavlink import mavutil

from missions.fieldfile import FieldFileError
from missions.fleet_flight import specs_from_fields
from missions.fleet_trial import fly_fleet_trial
from sim.gridworld import GridConfig

pytestmark = pytest.mark.slow
SMALL = ("--width", "8", "--height", "8", "--targets", "3")


@contextmanager
def fleet_sitl(tmp: Path, first: int, count: int, *args: str) -> Iterator[tuple[list[Path], list[GroundStation]]]:
    stations = [GroundStation(14550 + first + k) for k in range(count)]
    proc = uavsearch("sitl", "--instance", str(first), "--count", str(count), "--one-field", "--gcs-port-per-instance",
                     "--field-out", str(tmp / "field.json"), *SMALL, *args)
    out = Lines(proc)
    try:
        assert out.wait_for(f"uavsearch run --field {tmp / f'field-{first + count - 1}.json'}", 60), out.text
        assert until(lambda: all(s.seen.armed == [False] for s in stations), 30), "every vehicle is up, disarmed"
        yield [tmp / f"field-{first + k}.json" for k in range(count)], stations
    finally:
        stop_process(proc, 15)
        for s in stations:
            s.close()


def test_a_fleet_of_three_finds_every_target_with_no_separation_refused(tmp_path: Path) -> None:
    with fleet_sitl(tmp_path, 25, 3, "--speedup", "12", "--seed", "0") as (fields, stations):
        run = uavsearch("run", "--fleet", *map(str, fields), "--out", str(tmp_path / "run"))
        out, _ = run.communicate(timeout=120)
        assert run.returncode == 0, out
        assert "3/3 targets found by the team" in out and "0 setpoints refused" in out, out
        assert until(lambda: all(s.seen.armed[:3] == [False, True, False] for s in stations), 10), \
            [s.seen for s in stations]
        assert all(s.seen.max_alt_m > 2.5 and s.seen.landed_state == mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND
                   for s in stations), "each flew and landed"
    log = json.loads((tmp_path / "run" / "fleet_log.json").read_text())
    team = log["outcome"]["team"]
    assert len(team["finds"]) == 3 and team["separation_refused"] == 0 and team["min_separation_m"] >= 2.0, team
    assert {v for _, v, _ in team["finds"]} <= {0, 1, 2} and log["git_revision"]
    assert (tmp_path / "run" / "fleet.png").read_bytes()[:4] == b"\x89PNG"
    assert all((tmp_path / "run" / f"vehicle-{i}" / "search_log.json").exists() for i in range(3))


@pytest.mark.parametrize("how", ["cut", "kill"])
def test_a_vehicle_lost_mid_search_is_down_and_the_others_finish(tmp_path: Path, how: str) -> None:
    """cut: its link goes silent at round 2 (a cut FaultProxy: real UDP, nothing gets through):
    the companion loses it and its own offboard-loss failsafe lands it. kill: a ground station
    force-disarms it at round 2 (it falls): the companion sees it disarmed and takes it out.
    Either way the other two find all 3."""
    r = fly_fleet_trial(tmp_path, 3, GridConfig(width=8, height=8, n_targets=3), seed=0, speedup=12, plot=False,
                        **{how: (1, 2)})
    assert list(r["lost"]) == ["1"], r["lost"]
    assert how == "cut" or "disarmed" in r["lost"]["1"], r["lost"]  # cut: silence or the link error, whichever first
    assert r["outcome"] == 0 and r["truly_found"] == 3, r
    assert r["armed_after"] == [False, False, False] and max(r["height_after_m"]) < 0.3, "all down, the cut one too"
    assert r["separation_refused"] == 0 and r["min_true_separation_same_height_m"] >= 2.0, r


def test_sigterm_lands_every_vehicle(tmp_path: Path) -> None:
    with fleet_sitl(tmp_path, 28, 2, "--speedup", "8", "--seed", "3") as (fields, stations):
        run = uavsearch("run", "--fleet", *map(str, fields), "--out", str(tmp_path / "run"))
        assert until(lambda: all(s.armed_now and s.seen.alt_m > 2.5 for s in stations), 60), [s.seen for s in stations]
        time.sleep(1.0)  # a round or two into the search
        os.kill(run.pid, signal.SIGTERM)
        out, _ = run.communicate(timeout=90)
        assert run.returncode == 128 + signal.SIGTERM, out
        assert "interrupted by SIGTERM" in out and out.count("landed and disarmed") == 2, out
        assert until(lambda: not any(s.armed_now for s in stations), 10), [s.seen for s in stations]


def test_run_fleet_refuses_fields_that_are_not_one_fleets(tmp_path: Path) -> None:
    from missions.fieldfile import FieldSpec, write_field
    from sim.gridworld.geodesy import HomePosition

    g = GridConfig(width=8, height=8, n_targets=3)
    for k, team in enumerate((2, None)):
        write_field(tmp_path / f"f{k}.json", FieldSpec(HomePosition(51.0, -2.0, 30.0), g, connect=f"udpin:0.0.0.0:{k}",
                                                       team=team))
    with pytest.raises(FieldFileError, match="--one-field"):
        specs_from_fields([tmp_path / "f0.json", tmp_path / "f1.json"])


def test_a_fleet_on_a_real_field_searches_its_mask_behind_its_fence(tmp_path: Path) -> None:
    """`sitl --count 2 --one-field --field` on a small turned paddock with a pond (6 x 7 cells,
    36 searchable) and `run --fleet`: each vehicle starts on a searchable cell, gets the field's
    fence, decides only over searchable cells; the team finds both targets and both land.
    Seed 1: vehicle 0 finds both itself (the team, not its own count, ends the search)."""
    from test_field_flight import small_field
    from typer.testing import CliRunner

    from missions.cli import app
    from sim.field import load_field

    r = CliRunner().invoke(app, ["field", str(small_field(tmp_path / "paddock.geojson")), "--heading", "-120",
                                 "--out", str(tmp_path / "paddock")])
    assert r.exit_code == 0, r.output
    real = tmp_path / "paddock" / "field.json"
    mask = load_field(str(real)).mask
    stations = [GroundStation(14550 + 33 + k) for k in range(2)]
    proc = uavsearch("sitl", "--instance", "33", "--count", "2", "--one-field", "--gcs-port-per-instance", "--field",
                     str(real), "--targets", "2", "--speedup", "10", "--seed", "1", "--field-out", str(tmp_path / "f.json"))
    lines = Lines(proc)
    try:
        assert lines.wait_for(f"uavsearch run --field {tmp_path / 'f-34.json'}", 60), lines.text
        assert until(lambda: all(s.seen.armed == [False] for s in stations), 30), "every vehicle is up, disarmed"
        run = uavsearch("run", "--fleet", str(tmp_path / "f-33.json"), str(tmp_path / "f-34.json"),
                        "--out", str(tmp_path / "run"))
        out, _ = run.communicate(timeout=120)
        assert run.returncode == 0, out
        assert "2/2 targets found by the team" in out and "0 setpoints refused" in out, out
        assert out.count("fence: 8 vertices uploaded and read back (1 inclusion, 1 exclusion polygons)") == 2, out
        assert until(lambda: all(s.seen.armed[:3] == [False, True, False] for s in stations), 10), \
            [s.seen for s in stations]
    finally:
        stop_process(proc, 15)
        for s in stations:
            s.close()
    for i in range(2):
        cells = json.loads((tmp_path / "run" / f"vehicle-{i}" / "search_log.json").read_text())["cells"]
        assert cells and all(mask[y][x] for x, y in cells), (i, cells)
