"""`uavsearch demo --agents N` (issue 29): the fleet searches one field; a report and the tracks."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app

runner = CliRunner()


def test_the_fleet_demo_flies_two_vehicles_and_writes_the_report_and_the_tracks(tmp_path: Path) -> None:
    r = runner.invoke(app, ["demo", "--agents", "2", "--width", "6", "--height", "6", "--targets", "2",
                            "--seed", "1", "--speedup", "20", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    out = tmp_path / "fleet"
    rep = json.loads((out / "report.json").read_text())
    assert rep["truly_found"] == 2 and rep["separation_refused"] == 0 and rep["git_revision"], rep
    md = (out / "report.md").read_text()
    assert "2 UAVs searching one 6 x 6 field" in md and "![" in md and "(fleet.png)" in md
    assert (out / "fleet.png").stat().st_size > 10_000
    assert not (tmp_path / "table.md").exists(), "the fleet demo is not the evaluation"


def test_the_lone_demo_takes_no_field_size() -> None:
    r = runner.invoke(app, ["demo", "--width", "6", "--no-fly"])
    assert r.exit_code == 2 and "--agents" in r.output, r.output
