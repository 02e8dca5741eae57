import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app
from policy.evaluation import PAPER_TABLE1, markdown_table, run_eval
from sim.gridworld import GridConfig


def test_report_files(tmp_path: Path) -> None:
    doc = run_eval(["oracle", "ns"], GridConfig(), 100, 2, out=tmp_path, progress=False, echo=False)
    saved = json.loads((tmp_path / "results.json").read_text())
    assert saved["policies"]["ns"]["over_100_pct"] == doc["policies"]["ns"]["over_100_pct"]
    assert saved["git_revision"] and saved["created_utc"] and saved["seed"] == 2
    assert saved["config"]["n_targets"] == 5 and saved["episodes"] == 100
    for key in ("diff_lt_10_pct", "diff_le_10_pct", "recovery_rate_mean", "mean_moves", "targets_per_move"):
        assert key in saved["policies"]["ns"]
    md = (tmp_path / "table.md").read_text()
    assert "| ns | paper |" in md and "(g) recovery rate" in md and "0.260±0.113" in md
    for f in ("fig4_difference.png", "paths_ns.png", "paths_oracle.png"):
        assert (tmp_path / f).read_bytes()[:4] == b"\x89PNG"
    assert not list(tmp_path.glob(".*.tmp")), "no temporary files left behind"


def test_paper_rows_only_beside_the_base_case() -> None:
    doc = run_eval(["ns"], GridConfig(distribution="gaussian"), 20, 1, progress=False, echo=False)
    assert doc["paper_rows"] == {}
    md = markdown_table([("ns", doc["policies"]["ns"], None), ("x", PAPER_TABLE1["NS"], "NS")])
    assert md.count("| paper |") == 1 and "| ns | ours | - | - |" in md


def test_cli_json_is_only_json_and_names_unknown_policies(tmp_path: Path) -> None:
    runner = CliRunner()
    r = runner.invoke(app, ["eval", "-p", "ns", "-p", "lawnmower", "--episodes", "50", "--seed", "3",
                            "--json", "--out", str(tmp_path / "rep")])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert set(doc["policies"]) == {"ns", "lawnmower"}
    assert doc["policies"]["lawnmower"]["mean_moves"] > doc["policies"]["lawnmower"]["mean_optimal_moves"]
    assert (tmp_path / "rep" / "results.json").exists()
    r = runner.invoke(app, ["eval", "-p", "ns", "-p", "bogus"])
    text = " ".join(r.output.replace("│", " ").split())
    assert r.exit_code != 0 and "unknown policy bogus" in text and "lawnmower" in text
    (tmp_path / "file").write_text("x")
    r = runner.invoke(app, ["eval", "--episodes", "5", "--out", str(tmp_path / "file")])
    assert r.exit_code != 0
