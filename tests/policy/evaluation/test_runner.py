import json
from pathlib import Path

from policy.baselines import make_policy
from policy.evaluation import evaluate, run_eval
from sim.gridworld import GridConfig


def test_oracle_is_optimal_on_every_setting() -> None:
    for kw in ({}, {"motion": "herd", "distribution": "equidistant", "map_variant": "spatiotemporal"}):
        cfg = GridConfig(**kw)
        r = evaluate(make_policy("oracle", cfg), cfg, 300, seed=1, batch=128, progress=False)
        assert r.columns["optimal_pct"] == 100.0 and r.columns["success_pct"] == 100.0


def test_same_seed_same_result_and_batching_does_not_matter() -> None:
    cfg = GridConfig()
    a = evaluate(make_policy("ns", cfg), cfg, 200, seed=3, batch=200, progress=False)
    b = evaluate(make_policy("ns", cfg), cfg, 200, seed=3, batch=200, progress=False)
    assert (a.moves == b.moves).all()
    c = evaluate(make_policy("oracle", cfg), cfg, 200, seed=3, batch=64, progress=False)
    assert (c.optimal == a.optimal).all(), "every policy meets the same episodes"


def test_report_files(tmp_path: Path) -> None:
    doc = run_eval(["oracle", "ns"], GridConfig(), 100, 2, out=tmp_path, progress=False, echo=False)
    saved = json.loads((tmp_path / "results.json").read_text())
    assert saved["policies"]["ns"]["over_100_pct"] == doc["policies"]["ns"]["over_100_pct"]
    assert saved["git_revision"] and saved["seed"] == 2 and saved["config"]["n_targets"] == 5
    md = (tmp_path / "table.md").read_text()
    assert "| ns | paper |" in md and "(g) recovery rate" in md
    for f in ("fig4_difference.png", "paths_ns.png", "paths_oracle.png"):
        assert (tmp_path / f).read_bytes()[:4] == b"\x89PNG"
