"""Grid-world stepping speed, side by side in one run (issue 13):
- the batched numpy engine as shipped (observations computed from agent and target cells);
- the same engine observing through the reference functions (observations.views over a target
  occupancy grid, spatial_map, actions.valid_mask), as it did before;
- the torch engine (torch_batch.py) on CPU, and on CUDA when a GPU is present;
- the same episodes stepped one at a time through the gymnasium Env.
Steps/s count active episode-steps with an observation each. Run:
`PYTHONPATH=. python benchmarks/bench_gridworld.py`."""

from __future__ import annotations

import os
import time

import numpy as np
import torch

from sim.gridworld import BatchGridWorld, GridConfig, GridSearchEnv, sample_episodes
from sim.gridworld.actions import valid_mask
from sim.gridworld.observations import spatial_map, target_occupancy, views
from sim.gridworld.torch_batch import TorchGridWorld

#: CPU time of this process, not wall time: the machine is shared, and CPU time is what an idle
#: core would give (a wall clock here measures everyone else's load)
_clock = time.process_time


class ReferenceObservations(BatchGridWorld):
    """The engine with the observation path it had before issue 13."""

    def valid_actions(self) -> np.ndarray:
        return valid_mask(self.agent, self.cfg.width, self.cfg.height, self.n_actions)

    def observe(self) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.cfg
        v = views(self.agent, target_occupancy(self.targets(), cfg.width, cfg.height))
        if cfg.map_variant == "spatiotemporal":
            return v, np.stack([self.trail, self.recoveries], axis=1)
        return v, spatial_map(self.agent, self.visited, self.met if cfg.map_variant == "memory" else None)


def batched(cfg: GridConfig, n: int, seed: int, engine=BatchGridWorld, **kw) -> float:
    episodes = sample_episodes(cfg, n, seed)
    t0 = _clock()
    world = engine(episodes, seed, **kw)
    rng = np.random.default_rng(seed)
    steps = 0
    is_torch = engine is TorchGridWorld
    while not bool(world.done.all()):
        steps += int((~world.done).sum())
        world.observe()
        a = rng.integers(0, cfg.n_actions, n)
        world.step(torch.as_tensor(a) if is_torch else a)
    if is_torch and world.device.type == "cuda":
        torch.cuda.synchronize()
    return steps / (_clock() - t0)


def per_episode(cfg: GridConfig, n: int, seed: int) -> float:
    t0 = _clock()
    env = GridSearchEnv(cfg)
    rng = np.random.default_rng(seed)
    steps = 0
    for i in range(n):
        env.reset(seed=seed + i)
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(int(rng.integers(0, cfg.n_actions)))
            steps += 1
            done = term or trunc
    return steps / (_clock() - t0)


def main() -> None:
    torch.set_num_threads(1)  # CPU time is summed over threads: one thread keeps rates comparable
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; torch threads 1 (CPU-time rates); "
          f"GPU: {torch.cuda.get_device_name(0) if torch.cuda.is_available() else 'none'}; best of 3 interleaved rounds")
    cols = ["batched", "reference obs", "torch cpu"] + (["torch cuda"] if torch.cuda.is_available() else []) + \
        ["per-episode"]
    print(f"{'setting':<28}" + "".join(f"{c:>15}" for c in cols) + f"{'new/ref':>9}")
    for motion, dist, mp in [("static", "random", "spatial"), ("herd", "equidistant", "spatiotemporal")]:
        cfg = GridConfig(distribution=dist, motion=motion, map_variant=mp)
        runs = {
            "batched": lambda c=cfg: batched(c, 2000, 1),
            "reference obs": lambda c=cfg: batched(c, 2000, 1, ReferenceObservations),
            "torch cpu": lambda c=cfg: batched(c, 2000, 1, TorchGridWorld, device="cpu"),
            "per-episode": lambda c=cfg: per_episode(c, 40, 1),
        }
        if torch.cuda.is_available():
            runs["torch cuda"] = lambda c=cfg: batched(c, 200_000, 1, TorchGridWorld, device="cuda")
        best = dict.fromkeys(runs, 0.0)
        for _ in range(3):
            for name, run in runs.items():
                best[name] = max(best[name], run())
        ratio = best["batched"] / best["reference obs"]
        print(f"{motion + '/' + dist:<28}" + "".join(f"{best[c]:>15,.0f}" for c in cols) + f"{ratio:>8.2f}x")


if __name__ == "__main__":
    main()
