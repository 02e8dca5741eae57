"""Grid-world stepping speed: the batched numpy engine vs the same episodes stepped one at a
time through the gymnasium Env (the per-episode Python loop it replaces). Prints the ratio."""

from __future__ import annotations

import time

import numpy as np

from sim.gridworld import BatchGridWorld, GridConfig, GridSearchEnv, sample_episodes


def batched(cfg: GridConfig, n: int, seed: int) -> tuple[float, int]:
    t0 = time.perf_counter()
    world = BatchGridWorld(sample_episodes(cfg, n, seed), seed)
    rng = np.random.default_rng(seed)
    steps = 0
    while not world.done.all():
        steps += int((~world.done).sum())
        world.observe()
        world.step(rng.integers(0, cfg.n_actions, n))
    return time.perf_counter() - t0, steps


def per_episode(cfg: GridConfig, n: int, seed: int) -> tuple[float, int]:
    t0 = time.perf_counter()
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
    return time.perf_counter() - t0, steps


def main() -> None:
    print(f"{'setting':<28}{'batched steps/s':>18}{'per-episode steps/s':>22}{'ratio':>8}")
    for motion, dist, mp in [("static", "random", "spatial"), ("herd", "equidistant", "spatiotemporal")]:
        cfg = GridConfig(distribution=dist, motion=motion, map_variant=mp)
        tb, sb = batched(cfg, 2000, 1)
        tp, sp = per_episode(cfg, 40, 1)
        rb, rp = sb / tb, sp / tp
        print(f"{motion + '/' + dist:<28}{rb:>18,.0f}{rp:>22,.0f}{rb / rp:>7.1f}x")


if __name__ == "__main__":
    main()
