"""`eval --agents N` (issue 29): the team table through the CLI, JSON with mean_makespan."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from missions.cli import app


def test_eval_agents_json_reports_makespan_beside_todays_fields() -> None:
    r = CliRunner().invoke(app, ["eval", "--agents", "2", "-p", "belief", "-p", "lawnmower-strips", "--episodes", "20",
                                 "--seed", "3", "--json", "--comms-loss", "0.3", "--comms-delay", "2"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["agents"] == 2 and doc["comms"]["loss"] == 0.3
    for cols in doc["policies"].values():
        assert cols["mean_makespan"] == cols["mean_moves"] and "success_pct" in cols
    r = CliRunner().invoke(app, ["eval", "--agents", "2", "-p", "ns"])
    assert r.exit_code != 0 and "unknown team policy" in " ".join(r.output.replace("│", " ").split())


def test_quality_agents_writes_the_fleet_table(tmp_path) -> None:
    r = CliRunner().invoke(app, ["quality", "--agents", "2", "--setting", "random 10x10/5", "--episodes", "10",
                                 "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "fleet_search.json").read_text())
    cells = doc["table"]["random 10x10/5"]
    assert {"single belief x1", "belief x2", "belief, lossy x2", "belief-independent x2"} <= set(cells)
    assert doc["git_revision"] and doc["test_seed"] == 0
    assert "N=2 / single belief" in (tmp_path / "fleet_search.md").read_text()
