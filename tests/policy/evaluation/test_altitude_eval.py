"""Altitude levels through the CLI and the measurement (issue 27): eval --levels --detection
reports flight time, quality takes the levels, the altitude table is written with provenance."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app
from policy.evaluation.altitude import run_altitude, write_altitude
from policy.evaluation.quality import quality_task
from sim.gridworld import DetectionTable

TABLE = DetectionTable(((1, 1), (0.95, 0.9, 0.8), (0.85, 0.75, 0.6, 0.45)), (0, 0.002, 0.005))


def _table(tmp_path: Path) -> Path:
    path = tmp_path / "detection.json"
    path.write_text(json.dumps(TABLE.to_dict()))
    return path


def test_eval_with_levels_reports_flight_time(tmp_path: Path) -> None:
    r = CliRunner().invoke(app, ["eval", "-p", "belief", "--levels", "3", "--detection", str(_table(tmp_path)),
                                 "--episodes", "6", "--width", "12", "--height", "12", "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["config"]["levels"] == 3 and doc["config"]["detection"]["p_detect"][2][3] == 0.45
    row = doc["policies"]["belief"]
    assert row["success_pct"] == 100.0 and row["mean_flight_s"] > 0
    r = CliRunner().invoke(app, ["eval", "--levels", "2", "--detection", str(tmp_path / "none.json")])
    assert r.exit_code != 0 and "no detection table" in r.output


def test_quality_cell_and_altitude_table(tmp_path: Path) -> None:
    cell = quality_task("belief", "random", 6, 0, levels=3, detection=str(_table(tmp_path)))
    assert cell["all_found_pct"] == 100.0 and cell["mean_flight_s"] > 0
    assert "not applicable" in quality_task("dualstream", "random", 2, 0, levels=3,
                                            detection=str(_table(tmp_path)))["note"]
    doc = run_altitude(TABLE, episodes=4, seed=1, rows=("belief (single height)", "belief (levels)"),
                       settings=("random 20x20/10",))
    cells = doc["table"]["random 20x20/10"]
    assert cells["belief (single height)"]["levels"] == 1 and cells["belief (levels)"]["levels"] == 3
    assert cells["belief (single height)"]["ratio_to_single_height"] == 1.0
    md = write_altitude(doc, tmp_path / "out", note="provisional table")[1].read_text()
    assert "provisional table" in md and "| belief (levels) | 3 |" in md and doc["git_revision"]
