"""Ground-truth speed and the paper's Fig. 3, measured side by side in one run.

(a) PT: our batched Held-Karp vs brute force over all |R|! orders (the paper's method) on the
    same episodes, |R| = 5..9, with the speed-up ratio.
(a') lookahead PT for moving targets (random walk): the subset DP vs all |R|! orders, |R| = 3..7.
(b) 20k static episodes end to end: sampling + solving + writing the (I, M, a) dataset.
(c) Fig. 3: CU vs PT mean solution length and solve time for |R| = 2..8 (100 episodes each, as
    in the paper), and the histogram of |S_CU| - |S_PT|; written to results/.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from policy.data import synthesize
from policy.groundtruth import held_karp, lookahead_bruteforce, lookahead_dp, pt_bruteforce, solve
from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig, sample_episodes

RESULTS = Path(__file__).resolve().parent.parent / "results"


def timed(fn, *a):
    t0 = time.perf_counter()
    out = fn(*a)
    return out, time.perf_counter() - t0


def versus(title: str, ours: str, theirs: str, cases, motion: str, seed0: int, fast, slow, what: str) -> list[dict]:
    """Time our solver and the exhaustive one on the same episodes, check they agree, print the ratio."""
    rows = []
    print(f"{'|R|':>4}{'episodes':>10}{ours + ' s/ep':>16}{theirs + ' s/ep':>18}{'speed-up':>10}  {title}")
    for r, n in cases:
        ep = sample_episodes(GridConfig(n_targets=r, motion=motion), n, seed=seed0 + r)
        (mine, _), t_mine = timed(fast, ep)
        ref, t_ref = timed(slow, ep)
        assert (mine == ref).all(), f"{ours} disagrees with {what}"
        rows.append({"targets": r, "episodes": n, f"{ours}_s": t_mine / n, f"{theirs}_s": t_ref / n})
        print(f"{r:>4}{n:>10}{t_mine / n:>16.2e}{t_ref / n:>18.2e}{t_ref / t_mine:>9.0f}x")
    return rows


def pt_speed() -> list[dict]:
    return versus("(static)", "held_karp", "brute_force", [(5, 2000), (6, 1000), (7, 300), (8, 100), (9, 20)],
                  "static", 0, lambda ep: held_karp(ep.agent, ep.targets, None),
                  lambda ep: pt_bruteforce(ep.agent, ep.targets), "brute force")


def lookahead_speed() -> list[dict]:
    return versus("(random walk)", "dp", "all_orders", [(3, 500), (4, 300), (5, 100), (6, 30), (7, 6)],
                  "random_walk", 50, lambda ep: lookahead_dp(ep.agent, ep.paths, None),
                  lambda ep: lookahead_bruteforce(ep.agent, ep.paths), "the exhaustive search")


def end_to_end() -> float:
    with tempfile.TemporaryDirectory() as d:
        _, t = timed(lambda: synthesize(GridConfig(), 20_000, 0, Path(d) / "ds", progress=False))
    print(f"20k static random episodes -> dataset: {t:.1f} s (the paper reports PT as O(|R|!); ours is batched)")
    return t


def fig3(extra: dict | None = None) -> dict:
    out: dict = {"targets": [], "cu_len": [], "pt_len": [], "cu_s": [], "pt_s": [], "pt_dp_only_s": [],
                 "pt_bruteforce_s": [], "cu_optimal_pct": []}
    diffs = []
    for r in range(2, 9):
        ep = sample_episodes(GridConfig(n_targets=r), 100, seed=100 + r)
        cu, t_cu = timed(solve, ep, "cu", 0)
        # both solvers timed the same way: order (or choice) plus the moves, replayed in the world
        plans, t_pt = timed(solve, ep, "pt", 0)
        (pt, _), t_dp = timed(held_karp, ep.agent, ep.targets, None)
        _, t_bf = timed(pt_bruteforce, ep.agent, ep.targets)
        assert (plans.lengths == pt).all()
        out["pt_dp_only_s"].append(t_dp / 100)
        out["pt_bruteforce_s"].append(t_bf / 100)
        out["targets"].append(r)
        out["cu_len"].append(float(cu.lengths.mean()))
        out["pt_len"].append(float(pt.mean()))
        out["cu_s"].append(t_cu / 100)
        out["pt_s"].append(t_pt / 100)
        out["cu_optimal_pct"].append(float(100 * (cu.lengths == pt).mean()))
        diffs.append(cu.lengths - pt)
    d = np.concatenate(diffs)
    out["cu_optimal_pct_all"] = float(100 * (d == 0).mean())
    big = sample_episodes(GridConfig(), 2000, seed=7)
    out["cu_optimal_pct_R5_2000"] = float(100 * (solve(big, "cu", 0).lengths == held_karp(big.agent, big.targets)[0]).mean())
    print(f"CU optimal in {out['cu_optimal_pct_all']:.1f} % of instances over |R| = 2..8, "
          f"{out['cu_optimal_pct_R5_2000']:.1f} % of 2000 at |R| = 5 (paper: ~60 %)")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    ax[0].plot(out["targets"], out["cu_len"], "o-", label="CU")
    ax[0].plot(out["targets"], out["pt_len"], "s-", label="PT (optimal)")
    ax[0].set(xlabel="|R|", ylabel="mean |S|", title="solution length")
    ax[0].legend()
    ax[1].semilogy(out["targets"], out["cu_s"], "o-", label="CU")
    ax[1].semilogy(out["targets"], out["pt_s"], "s-", label="PT (Held-Karp + moves)")
    ax[1].semilogy(out["targets"], out["pt_dp_only_s"], "s:", label="PT order only (Held-Karp)")
    ax[1].semilogy(out["targets"], out["pt_bruteforce_s"], "x--", label="PT order, all |R|! (paper)")
    ax[1].set(xlabel="|R|", ylabel="seconds per episode (batches of 100)", title="solve time")
    ax[1].legend(fontsize=7)
    ax[2].hist(d, bins=np.arange(-0.5, d.max() + 1.5), density=True)
    ax[2].set(xlabel="|S_CU| - |S_PT|", ylabel="fraction", title="CU vs PT, |R| = 2..8")
    fig.tight_layout()
    RESULTS.mkdir(exist_ok=True)
    with atomic_open(RESULTS / "fig3_cu_vs_pt.png", "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    cfg = {"episodes_per_R": 100, "grid": "10x10", "distribution": "random", "motion": "static",
           "seeds": "sample_episodes seed 100 + |R|, CU tie-break seed 0"}
    atomic_write_json(RESULTS / "fig3_cu_vs_pt.json", stamp(cfg, 100, **out, **(extra or {})))
    return out


def main() -> None:
    speed = pt_speed()
    moving = lookahead_speed()
    e2e = end_to_end()
    fig3(extra={"pt_speed": speed, "lookahead_speed": moving, "end_to_end_20k_s": e2e})


if __name__ == "__main__":
    main()
