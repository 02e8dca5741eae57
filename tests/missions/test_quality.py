import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from missions.cli import app

runner = CliRunner()


@pytest.mark.slow  # ~15 s alone: the hard-map GPS cells run to t_e
def test_quality_writes_table_json_and_plots(tmp_path: Path) -> None:
    out = tmp_path / "q"
    r = runner.invoke(app, [
        "quality", "--episodes", "24", "--gps-episodes", "8", "--policy", "oracle", "--policy", "belief",
        "--policy", "cu", "--setting", "random", "--setting", "random walk", "--out", str(out),
    ])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "search_quality.json").read_text())
    assert doc["test_seed"] == 0 and doc["episodes"] == 24 and doc["git_revision"]
    rnd = doc["table"]["random"]
    assert rnd["oracle"]["all_found_pct"] == 100.0 and rnd["belief"]["all_found_pct"] == 100.0
    assert rnd["belief"]["mean_moves"] > rnd["oracle"]["mean_moves"]  # the oracle is a lower bound
    assert "not applicable" in doc["table"]["random walk"]["cu"]["note"]  # CU: static targets only
    assert set(doc["gps"]["belief"]) >= {"kalman/hard/0.0", "kalman/probabilistic/1.0", "fix/hard/2.0"}
    md = (out / "search_quality.md").read_text()
    assert "| belief |" in md and "## GPS noise" in md and "random walk, cu: not applicable" in md
    assert (out / "search_quality.png").stat().st_size > 0 and (out / "search_quality_gps.png").exists()


def test_quality_rejects_unknown_rows_and_settings(tmp_path: Path) -> None:
    r = runner.invoke(app, ["quality", "--policy", "bogus", "--out", str(tmp_path)])
    assert r.exit_code != 0 and "bogus" in r.output
    r = runner.invoke(app, ["quality", "--setting", "mars", "--out", str(tmp_path)])
    assert r.exit_code != 0 and "mars" in r.output


def test_quality_reuse_runs_only_the_missing_cells(tmp_path: Path) -> None:
    out = tmp_path / "q"
    base = ["quality", "--episodes", "16", "--no-gps", "--setting", "random", "--out", str(out)]
    r = runner.invoke(app, [*base, "--policy", "oracle", "--policy", "lawnmower"])
    assert r.exit_code == 0, r.output
    first = json.loads((out / "search_quality.json").read_text())
    r = runner.invoke(app, [*base, "--policy", "oracle", "--policy", "lawnmower", "--policy", "frontier",
                            "--reuse", str(out / "search_quality.json")])
    assert r.exit_code == 0, r.output
    second = json.loads((out / "search_quality.json").read_text())
    assert second["cells_run"] == 1  # frontier only
    for row in ("oracle", "lawnmower"):
        cell = second["table"]["random"][row]
        assert cell["reused_from"] == first["git_revision"]
        assert cell["mean_moves"] == first["table"]["random"][row]["mean_moves"]
    assert "reused_from" not in second["table"]["random"]["frontier"]
    assert "reused from the run at" in (out / "search_quality.md").read_text()
    r = runner.invoke(app, [*base, "--policy", "oracle", "--policy", "lawnmower", "--policy", "frontier",
                            "--reuse", str(out / "search_quality.json"), "--refresh", "lawnmower"])
    assert r.exit_code == 0, r.output
    third = json.loads((out / "search_quality.json").read_text())
    assert third["cells_run"] == 1 and "reused_from" not in third["table"]["random"]["lawnmower"]
