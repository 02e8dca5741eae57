"""Does our small default score at least as well as the paper's layer sizes? Both trained on
the same static random PT dataset with the same budget, evaluated on the same test episodes;
writes results/architecture_comparison.md (and .json) with the numbers side by side."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from policy.data import synthesize
from policy.evaluation import evaluate
from policy.nn import load_policy
from policy.training import TrainConfig, train
from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig

RESULTS = Path(__file__).resolve().parent.parent / "results"


def main(episodes: int = 2000, epochs: int = 3, test: int = 1000, seed: int = 0) -> None:
    grid = GridConfig()
    rows = {}
    with tempfile.TemporaryDirectory() as d:
        ds = synthesize(grid, episodes, seed, Path(d) / "ds", progress=False)
        for arch in ("small", "paper"):
            tc = TrainConfig(arch=arch, epochs=epochs, folds=5, run_folds=1, optimizer="adam", seed=seed)
            t0 = time.perf_counter()
            s = train(ds, Path(d) / arch, tc, progress=False)
            secs = time.perf_counter() - t0
            r = evaluate(load_policy(Path(d) / arch / "model.pt", cfg=grid), grid, test, seed + 1, progress=False)
            rows[arch] = r.columns | {"val_acc": 100 * s["cv_acc_mean"], "train_s": secs, "samples": s["samples"]}
            print(arch, {k: round(v, 3) for k, v in rows[arch].items() if isinstance(v, float)})
    keys = [("val_acc", "held-out accuracy %"), ("optimal_pct", "optimal %"), ("diff_lt_10_pct", "<10 diff %"),
            ("over_100_pct", ">100 moves %"), ("recovery_rate_mean", "recovery rate"), ("mean_moves", "mean moves"),
            ("train_s", "training time (s)")]
    md = ["# Architecture comparison: `small` (default) vs `paper`", "",
          f"Static random targets, {episodes} PT training episodes ({rows['small']['samples']} samples), "
          f"{epochs} epochs of Adam, one held-out fold of 5; {test} test episodes (seed {seed + 1}).", "",
          "| metric | small | paper |", "|---|---|---|"]
    md += [f"| {label} | {rows['small'][k]:.3f} | {rows['paper'][k]:.3f} |" for k, label in keys]
    keep = rows["small"]["recovery_rate_mean"] >= rows["paper"]["recovery_rate_mean"] - 0.005 and \
        rows["small"]["optimal_pct"] >= rows["paper"]["optimal_pct"] - 0.5
    md += ["", f"Verdict: the small default {'scores at least as well' if keep else 'scores worse'} on the static "
           "random row (recovery rate within 0.005 and optimal % within 0.5 points, or better)."
           + ("" if keep else " The default should be revisited."), ""]
    RESULTS.mkdir(exist_ok=True)
    with atomic_open(RESULTS / "architecture_comparison.md", "w") as f:
        f.write("\n".join(md))
    atomic_write_json(RESULTS / "architecture_comparison.json",
                      stamp(grid.to_dict(), seed, episodes=episodes, epochs=epochs, test=test, rows=rows, keep_small=keep))


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
