"""Decision latency of the search network at batch 1 on one CPU thread, beside the shipped
dual-stream network, in one run on the same episodes: p50/p99 of one whole decision (the belief
update from the observation, the planes, the egocentric window, the forward pass, the argmax)
on 10 x 10 and 20 x 20 fields. Goal: searchnet p99 < 1 ms at batch 1.

    .venv/bin/python benchmarks/bench_searchnet.py [decisions per setting (default 2000)]
"""

from __future__ import annotations

import sys
import time

import numpy as np
import torch

from policy.base import observe
from policy.baselines.registry import make_policy
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


def latencies(name: str, cfg: GridConfig, decisions: int, seed: int = 7) -> np.ndarray:
    """Seconds per decision for single episodes (batch 1), played to the end one after another."""
    pol = make_policy(name, cfg)
    ts: list[float] = []
    ep_seed = seed
    while len(ts) < decisions:
        ep = sample_episodes(cfg, 1, ep_seed)
        pol.reset(cfg, 1, ep_seed, None)
        world = BatchGridWorld(ep, ep_seed)
        while not world.done.all() and len(ts) < decisions:
            obs = observe(world)
            t0 = time.perf_counter()
            a = pol.act(obs)
            ts.append(time.perf_counter() - t0)
            world.step(a)
        ep_seed += 1
    return np.array(ts[20:])  # drop the warm-up


def main() -> None:
    decisions = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    torch.set_num_threads(1)
    print(f"decision latency at batch 1, 1 torch thread, {decisions} decisions per row (ms)")
    print(f"{'policy':<12}{'field':>8}{'p50':>9}{'p99':>9}{'p99 / dualstream':>18}")
    for cfg in (GridConfig(), GridConfig(width=20, height=20, n_targets=10)):
        ref = None
        for name in ("dualstream", "searchnet"):
            if name == "dualstream" and cfg.width != 10:
                continue  # the dual-stream network is built for its 10 x 10 training map
            ts = latencies(name, cfg, decisions)
            p50, p99 = 1e3 * np.percentile(ts, 50), 1e3 * np.percentile(ts, 99)
            ref = p99 if name == "dualstream" else ref
            ratio = f"{p99 / ref:.2f}" if ref else "-"
            print(f"{name:<12}{cfg.width}x{cfg.height:<5}{p50:9.3f}{p99:9.3f}{ratio:>18}")
    print("goal: searchnet p99 < 1 ms")


if __name__ == "__main__":
    main()
