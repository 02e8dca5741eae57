"""Evaluation throughput: the lock-step batched runner vs the same code one episode at a time
(batch = 1, the per-episode Python loop it replaces), for NS and the oracle, side by side.

    .venv/bin/python benchmarks/bench_eval.py
"""

from __future__ import annotations

import os
import time

from policy.baselines import make_policy
from policy.evaluation import evaluate
from sim.gridworld import GridConfig


def rate(name: str, episodes: int, batch: int) -> float:
    """Episodes per second, including the optimal lengths the runner computes."""
    cfg = GridConfig()
    t0 = time.perf_counter()
    evaluate(make_policy(name, cfg), cfg, episodes, seed=1, batch=batch, progress=False)
    return episodes / (time.perf_counter() - t0)


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; 10x10, 5 static targets")
    print(f"{'policy':<10}{'batched ep/s':>14}{'one-by-one ep/s':>17}{'ratio':>8}")
    for name in ("ns", "oracle"):
        b = rate(name, 5000, 5000)
        s = rate(name, 200, 1)
        print(f"{name:<10}{b:>14,.0f}{s:>17,.0f}{b / s:>7.0f}x")


if __name__ == "__main__":
    main()
