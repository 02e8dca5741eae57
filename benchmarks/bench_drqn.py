"""DRQN training step on this machine, ours vs the straightforward one, side by side on the same
replay batches: every frame through the convolutions and a per-tensor Adam, against distinct
frames only (a 3x3 view takes few values) and a fused Adam. Same function, same gradients.
Also: what the paper's 20k episodes would cost at the measured rate.

    .venv/bin/python benchmarks/bench_drqn.py [threads (default 1)]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
import torch

from policy.drqn import DrqnConfig, DrqnLearner, drqn_view
from sim.gridworld import GridConfig


class PlainLearner(DrqnLearner):
    """The same learner, rendering and convolving every frame, Adam one tensor at a time."""

    def __init__(self, *a) -> None:
        super().__init__(*a)
        self.opt = torch.optim.Adam(self.net.parameters(), lr=self.cfg.lr, foreach=False)

    def frames(self, views: np.ndarray, found: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        lead = views.shape[:-3]
        fr = drqn_view(views.reshape(-1, 3, 3, 3), found.reshape(-1, 3, 3), self.cfg.image)
        return torch.from_numpy(fr), torch.arange(len(fr)).reshape(lead)


def step_ms(learner: DrqnLearner, steps: int) -> float:
    for _ in range(3):
        learner.learn()
    t0 = time.perf_counter()
    for _ in range(steps):
        learner.learn()
    return 1000 * (time.perf_counter() - t0) / steps


def main(threads: int = 1, steps: int = 40) -> None:
    torch.set_num_threads(threads)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores")
    cfg, grid = DrqnConfig(warmup_steps=10**9), GridConfig()
    ours, plain = DrqnLearner(cfg, grid, 0), PlainLearner(cfg, grid, 0)
    ours.play_chunk(16)  # a replay of random-policy episodes (the same for both: same seed)
    plain.replay.episodes = list(ours.replay.episodes)
    ms_plain, ms_ours = step_ms(plain, steps), step_ms(ours, steps)
    print(f"{'training step':<32}{'plain ms':>10}{'ours ms':>10}{'speed-up':>10}")
    print(f"{'4 x 9 frames, online + target':<32}{ms_plain:>10.1f}{ms_ours:>10.1f}{ms_plain / ms_ours:>9.2f}x")
    steps_20k = 20_000 * 200 / cfg.update_every  # ~200 moves an episode once it learns
    print(f"the paper's 20k episodes (~{steps_20k / 1e6:.1f} M training steps): "
          f"{steps_20k * ms_ours / 3.6e6:.1f} h at this rate (plain: {steps_20k * ms_plain / 3.6e6:.1f} h)")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
