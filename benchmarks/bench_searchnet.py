"""Decision latency of the search network at batch 1 on one CPU thread, beside the shipped
dual-stream network, measured interleaved (one decision of each in turn on the same episode),
so both see the same machine load. A decision is everything the flight pays per step: the
belief update from the observation, the planes, the egocentric window, the forward pass, the
argmax (and for both, the paper's loop guard on static targets). 20 x 20 runs searchnet alone
(the dual-stream network is built for its 10 x 10 map). Goal: searchnet p99 < 1 ms.

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


def latencies(names: tuple[str, ...], cfg: GridConfig, decisions: int, seed: int = 7) -> dict[str, np.ndarray]:
    """Seconds per decision for each policy, single episodes (batch 1) played to the end in
    turn; the world follows the first policy's moves, the others decide on the same states."""
    pols = {n: make_policy(n, cfg) for n in names}
    ts: dict[str, list[float]] = {n: [] for n in names}
    ep_seed = seed
    while len(ts[names[0]]) < decisions:
        ep = sample_episodes(cfg, 1, ep_seed)
        for p in pols.values():
            p.reset(cfg, 1, ep_seed, None)
        world = BatchGridWorld(ep, ep_seed)
        while not world.done.all() and len(ts[names[0]]) < decisions:
            obs = observe(world)
            acts = {}
            for n, p in pols.items():
                t0 = time.perf_counter()
                acts[n] = p.act(obs)
                ts[n].append(time.perf_counter() - t0)
            world.step(acts[names[0]])
        ep_seed += 1
    return {n: np.array(v[20:]) for n, v in ts.items()}  # drop the warm-up


def main() -> None:
    decisions = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    torch.set_num_threads(1)
    print(f"decision latency at batch 1, 1 torch thread, {decisions} decisions per row (ms), interleaved")
    print(f"{'policy':<12}{'field':>8}{'p50':>9}{'p99':>9}{'p50 ratio':>11}{'p99 ratio':>11}")
    for cfg, names in ((GridConfig(), ("searchnet", "dualstream")),
                       (GridConfig(width=20, height=20, n_targets=10), ("searchnet",))):
        res = latencies(names, cfg, decisions)
        ref = res.get("dualstream")
        for n, ts in res.items():
            p50, p99 = 1e3 * np.percentile(ts, 50), 1e3 * np.percentile(ts, 99)
            r50 = f"{np.percentile(ts, 50) / np.percentile(ref, 50):.2f}" if ref is not None else "-"
            r99 = f"{np.percentile(ts, 99) / np.percentile(ref, 99):.2f}" if ref is not None else "-"
            print(f"{n:<12}{cfg.width}x{cfg.height:<5}{p50:9.3f}{p99:9.3f}{r50:>11}{r99:>11}")
    print("ratios: searchnet / dualstream on the same states; goal: searchnet p99 < 1 ms")


if __name__ == "__main__":
    main()
