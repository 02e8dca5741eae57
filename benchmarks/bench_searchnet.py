"""Decision latency at batch 1 on one thread: the search network beside the shipped dual-stream
network and the `belief` planner (the flight default), measured interleaved on the same states
(every policy decides on each state in turn, the order rotating), so all see the same load.

A decision is everything the flight's policy service pays per move: the belief update from the
observation, the planes, the egocentric window, the forward pass, the mask and the argmax, and
the paper's loop guard on static targets (searchnet and dualstream alike). Rows:
- searchnet:        the shipped decision path (belief update on the cells in view, the forward
                    through policy.searchnet.infer.FastSearchNet);
- searchnet-torch:  the reference path (SearchNet's torch forward); its actions are checked
                    against searchnet's on every state ("same actions");
- dualstream:       the paper's network (10 x 10 only: its map is built for it);
- belief:           the belief planner at batch 1.
Each is timed by the wall clock (what the flight waits) and by the thread's CPU time (what the
decision costs; preemption by other processes on a shared machine inflates only the wall clock).
The machine's load average is printed with every round. Goal (issue 11): searchnet p99 < 1 ms.

    python benchmarks/bench_searchnet.py [decisions per round (2000)] [rounds (3)]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
import torch

from policy.base import Policy, observe
from policy.baselines.registry import make_policy
from policy.loops import LoopGuard
from policy.nn import shipped_checkpoint
from policy.searchnet import load_searchnet_policy
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

GOAL_MS = 1.0


def policies(cfg: GridConfig) -> dict[str, Policy]:
    ref = LoopGuard(load_searchnet_policy(shipped_checkpoint("searchnet_static_random"), cfg, fast=False))
    out = {"searchnet": make_policy("searchnet", cfg), "searchnet-torch": ref}
    if (cfg.width, cfg.height) == (10, 10):
        out["dualstream"] = make_policy("dualstream", cfg)
    out["belief"] = make_policy("belief", cfg)
    return out


def latencies(cfg: GridConfig, decisions: int, seed: int) -> tuple[dict[str, np.ndarray], int]:
    """{name: (k, 2) seconds (wall, thread CPU)} per decision, batch-1 episodes played to the end
    in turn; the world follows searchnet's moves. Also the states where searchnet-torch chose
    another action than searchnet."""
    pols = policies(cfg)
    names = list(pols)
    ts: dict[str, list[tuple[int, int]]] = {n: [] for n in names}
    differ, ep_seed, k = 0, seed, 0
    while len(ts[names[0]]) < decisions + 20:
        ep = sample_episodes(cfg, 1, ep_seed)
        for p in pols.values():
            p.reset(cfg, 1, ep_seed, None)
        world = BatchGridWorld(ep, ep_seed)
        while not world.done.all() and len(ts[names[0]]) < decisions + 20:
            obs = observe(world)
            acts = {}
            k += 1
            for n in names[k % len(names):] + names[: k % len(names)]:
                w0, c0 = time.perf_counter_ns(), time.thread_time_ns()
                acts[n] = pols[n].act(obs)
                ts[n].append((time.perf_counter_ns() - w0, time.thread_time_ns() - c0))
            differ += int(not np.array_equal(acts["searchnet"], acts["searchnet-torch"]))
            world.step(acts["searchnet"])
        ep_seed += 1
    return {n: np.array(v[20:]) / 1e9 for n, v in ts.items()}, differ  # drop the warm-up


def table(res: dict[str, np.ndarray], field: str) -> list[str]:
    ref = res.get("dualstream")
    rows = []
    for n, t in res.items():
        q = 1e3 * np.percentile(t, [50, 99], axis=0)  # (p50, p99) x (wall, cpu), ms
        r50 = f"{q[0, 0] / (1e3 * np.percentile(ref[:, 0], 50)):.2f}" if ref is not None else "-"
        r99 = f"{q[1, 0] / (1e3 * np.percentile(ref[:, 0], 99)):.2f}" if ref is not None else "-"
        rows.append(f"{n:<16}{field:>7}{q[0, 0]:9.3f}{q[1, 0]:9.3f}{q[0, 1]:9.3f}{q[1, 1]:9.3f}{r50:>9}{r99:>9}")
    return rows


def main() -> None:
    decisions = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    torch.set_num_threads(1)
    print(f"decision latency at batch 1, 1 torch thread, {decisions} decisions per policy and round, "
          f"interleaved; ms; ratios: wall clock / dualstream's on the same states; {os.cpu_count()} CPUs")
    best = np.inf
    for r in range(rounds):
        load0 = os.getloadavg()[0]
        print(f"\nround {r + 1}: load average {load0:.2f} at the start")
        print(f"{'policy':<16}{'field':>7}{'p50':>9}{'p99':>9}{'cpu p50':>9}{'cpu p99':>9}{'r p50':>9}{'r p99':>9}")
        for cfg in (GridConfig(), GridConfig(width=20, height=20, n_targets=10)):
            res, differ = latencies(cfg, decisions, seed=7 + 1000 * r)
            for line in table(res, f"{cfg.width}x{cfg.height}"):
                print(line)
            print(f"{'':<16}{'':>7}  searchnet and searchnet-torch chose the same action on "
                  f"{len(res['searchnet']) + 20 - differ}/{len(res['searchnet']) + 20} states")
            if (cfg.width, cfg.height) == (10, 10):
                best = min(best, 1e3 * np.percentile(res["searchnet"][:, 0], 99))
        print(f"load average {os.getloadavg()[0]:.2f} at the end")
    print(f"\nsearchnet 10x10 p99 (wall clock), best round: {best:.3f} ms; goal < {GOAL_MS} ms: "
          f"{'met' if best < GOAL_MS else 'not met'}")


if __name__ == "__main__":
    main()
