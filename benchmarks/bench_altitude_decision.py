"""Decision latency of `belief` with altitude levels at batch 1 (the flight: one vehicle, one
decision a move), beside single-height `belief` on the same field in the same run (issue 27's
goal: p99 < 2 ms on 20 x 20, L = 3, < 20 ms on 30 x 30).

Both planners fly their own episodes (the same seeds: the same agent and target cells); each
act() is timed by thread CPU time (what the planner costs, not what the other helpers on this
machine take from it), over whole episodes, after one warm-up episode.

    PYTHONPATH=. python benchmarks/bench_altitude_decision.py [--episodes N] [--out results/altitude/decision_latency.json]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from policy.base import observe
from policy.planner import BeliefPlanner
from provenance import atomic_write_json, stamp
from sim.gridworld import BatchGridWorld, DetectionTable, GridConfig, sample_episodes

ROOT = Path(__file__).resolve().parent.parent
TABLE = ROOT / "sim/gridworld/data/detection.json"
FIELDS = ((20, 20, 10, 300, 2.0), (30, 30, 15, 1000, 20.0))  # width, height, targets, t_e, p99 goal ms


def decisions_ms(cfg: GridConfig, episodes: int, seed: int) -> np.ndarray:
    """Thread CPU ms of every act() over `episodes` single-episode runs (seeds seed + i)."""
    out: list[int] = []
    for i in range(-1, episodes):  # episode -1: the warm-up, not counted
        s = seed + max(i, 0)
        world = BatchGridWorld(sample_episodes(cfg, 1, s), s)
        pol = BeliefPlanner()
        pol.reset(cfg, 1, s)
        while not world.done.all():
            obs = observe(world)
            t0 = time.thread_time_ns()
            a = pol.act(obs)
            if i >= 0:
                out.append(time.thread_time_ns() - t0)
            world.step(a)
    return np.array(out) / 1e6


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=10)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None, help="also write the numbers here (JSON, provenance)")
    a = ap.parse_args(argv)
    table = DetectionTable.load(TABLE)
    print(f"belief act() at batch 1, ms of thread CPU time, {a.episodes} episodes per row (seeds {a.seed}.."
          f"{a.seed + a.episodes - 1}); load average {os.getloadavg()[0]:.2f}")
    print(f"{'field':<14} {'planner':<18} {'decisions':>9} {'p50':>7} {'p99':>7} {'max':>7}  p99 x single  goal")
    rows = []
    for w, h, r, t_e, goal in FIELDS:
        base = dict(width=w, height=h, n_targets=r, t_e=t_e)
        res = {}
        for tag, cfg in (("single height", GridConfig(**base)),
                         ("levels (L = 3)", GridConfig(**base, levels=3, detection=table))):
            ms = decisions_ms(cfg, a.episodes, a.seed)
            res[tag] = {"decisions": int(ms.size), "p50_ms": float(np.percentile(ms, 50)),
                        "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max())}
        ratio = res["levels (L = 3)"]["p99_ms"] / res["single height"]["p99_ms"]
        for tag, c in res.items():
            extra = f"  {ratio:11.2f}  p99 < {goal:g} ms: {c['p99_ms'] < goal}" if tag.startswith("levels") else ""
            print(f"{f'{w}x{h}/{r}':<14} {tag:<18} {c['decisions']:>9} {c['p50_ms']:>7.3f} {c['p99_ms']:>7.3f} "
                  f"{c['max_ms']:>7.3f}{extra}")
        rows.append({"field": f"{w}x{h}/{r}", "t_e": t_e, "goal_p99_ms": goal, "p99_ratio_levels_to_single": ratio,
                     "p50_ratio_levels_to_single": res["levels (L = 3)"]["p50_ms"] / res["single height"]["p50_ms"],
                     **res})
    if a.out is not None:
        atomic_write_json(a.out, stamp({"episodes": a.episodes, "batch": 1, "timer": "thread CPU time",
                                        "detection": str(TABLE.relative_to(ROOT))}, a.seed, rows=rows,
                                       load_average=os.getloadavg()[0]))
        print(a.out)


if __name__ == "__main__":
    main()
