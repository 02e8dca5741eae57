"""`uavsearch flight-table --agents N`: the fleet flights measured from the CLI (issue 29)."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app

runner = CliRunner()


def test_a_fleet_table_flies_and_scores_every_seed(tmp_path: Path) -> None:
    r = runner.invoke(app, ["flight-table", "--agents", "2", "--width", "6", "--height", "6", "--targets", "2",
                            "--seeds", "1", "--speedup", "20", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "fleet_flights.json").read_text())
    (row,) = doc["flights"]
    assert row["truly_found"] == 2 and row["separation_refused"] == 0, row
    assert row["min_true_separation_same_height_m"] >= 2.0 and row["moves"] >= row["grid_makespan"] * 0.5, row
    assert doc["config"]["vehicles"] == 2 and doc["git_revision"] and (tmp_path / "fleet_flights.md").is_file()


def test_a_fleet_table_refuses_what_a_fleet_does_not_fly_yet(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.delenv("PX4_SITL", raising=False)  # a real autopilot's fleet needs its binary
    for extra, hint in ((["--autopilot", "px4"], "--autopilot"), (["--levels", "3"], "--levels"),
                        (["--camera", "video"], "--camera")):
        r = runner.invoke(app, ["flight-table", "--agents", "3", *extra, "--out", str(tmp_path)])
        assert r.exit_code == 2 and hint in r.output, r.output
