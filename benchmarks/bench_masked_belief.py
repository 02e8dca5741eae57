"""`belief` on a large masked field (issue 28): decision time and memory, against a small field
of the same shape measured in the same run.

The large field: 60 x 50 cells, 20 % masked (a corner cut off and two round holes, like a
paddock with a pond and a copse): about 2,400 searchable cells, 20 static targets. The small
one: the same shape at a fifth of the size per side (12 x 10). One episode at a time (the
flight decides at batch 1), every decision timed by thread CPU time. Goals: p99 < 50 ms on
the large field; planner + belief memory linear in cells (bytes per cell about the same on
both fields).

    PYTHONPATH=. python benchmarks/bench_masked_belief.py [EPISODES (default 5)]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

from policy.base import observe
from policy.planner import BeliefPlanner
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


def paddock(w: int, h: int) -> np.ndarray:
    """(h, w) bool: the field, scaled to w x h: a corner cut off and two round holes (~20 %)."""
    ys, xs = np.mgrid[0:h, 0:w]
    fx, fy = (xs + 0.5) / w, (ys + 0.5) / h
    cut = fx + fy < 0.42
    pond = (fx - 0.67) ** 2 + ((fy - 0.5) * h / w) ** 2 < 0.118 ** 2
    copse = (fx - 0.33) ** 2 + ((fy - 0.7) * h / w) ** 2 < 0.1 ** 2
    return ~(cut | pond | copse)


def _nbytes(obj: object, seen: set[int] | None = None, depth: int = 0) -> int:
    """Bytes of the numpy arrays an object holds (attributes, dicts, tuples; 3 levels)."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 3:
        return 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return obj.nbytes if obj.base is None else 0
    if isinstance(obj, dict):
        return sum(_nbytes(v, seen, depth + 1) for v in obj.values())
    if isinstance(obj, list | tuple):
        return sum(_nbytes(v, seen, depth + 1) for v in obj)
    if hasattr(obj, "__dict__"):
        return sum(_nbytes(v, seen, depth + 1) for v in vars(obj).values())
    return 0


def measure(w: int, h: int, targets: int, episodes: int) -> dict:
    mask = paddock(w, h)
    cfg = GridConfig(width=w, height=h, n_targets=targets, t_e=4 * w * h)
    times: list[float] = []
    peak = 0
    moves = []
    for seed in range(episodes):
        ep = sample_episodes(cfg, 1, 100 + seed, mask)
        world = BatchGridWorld(ep, 100 + seed)
        pol = BeliefPlanner()
        pol.reset(cfg, 1, 100 + seed)
        while not world.done.all():
            obs = observe(world)
            t0 = time.thread_time_ns()
            a = pol.act(obs)
            times.append((time.thread_time_ns() - t0) / 1e6)
            world.step(a)
            if world.t[0] % 50 == 1:
                peak = max(peak, _nbytes(pol))
        peak = max(peak, _nbytes(pol))
        moves.append(int(world.t[0]))
    ts = np.array(times)
    cells = int(mask.sum())
    return {"grid": f"{w} x {h}", "searchable": cells, "masked_pct": 100 * (1 - mask.mean()), "targets": targets,
            "decisions": len(ts), "p50_ms": float(np.percentile(ts, 50)), "p99_ms": float(np.percentile(ts, 99)),
            "max_ms": float(ts.max()), "bytes": peak, "bytes_per_cell": peak / (w * h),
            "mean_moves": float(np.mean(moves)), "found_all": bool(world.success.all())}


def main() -> None:
    episodes = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    print(f"belief on masked fields, batch 1, thread CPU time per decision; load average {os.getloadavg()[0]:.2f}")
    small = measure(12, 10, 4, episodes)
    large = measure(60, 50, 20, episodes)
    for r in (small, large):
        print(f"  {r['grid']} ({r['searchable']} searchable, {r['masked_pct']:.0f} % masked, {r['targets']} targets): "
              f"{r['decisions']} decisions, p50 {r['p50_ms']:.2f} ms, p99 {r['p99_ms']:.2f} ms, max {r['max_ms']:.1f} ms; "
              f"planner + belief {r['bytes'] / 1e6:.2f} MB = {r['bytes_per_cell']:.0f} B per grid cell; "
              f"mean moves {r['mean_moves']:.0f}")
    print(f"large / small: cells x{large['searchable'] / small['searchable']:.1f}, "
          f"p99 x{large['p99_ms'] / small['p99_ms']:.1f}, memory x{large['bytes'] / small['bytes']:.1f} "
          f"(per cell x{large['bytes_per_cell'] / small['bytes_per_cell']:.2f}: 1 = linear)")
    print(f"goal p99 < 50 ms on the large field: {'met' if large['p99_ms'] < 50 else 'NOT met'}")


if __name__ == "__main__":
    main()
