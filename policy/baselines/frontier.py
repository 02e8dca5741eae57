"""A frontier-greedy explorer: NS's target rule, but exploring towards the nearest unvisited
cell (Manhattan distance, which equals BFS distance on an obstacle-free grid; ties at random)
instead of by the vote."""

from __future__ import annotations

import numpy as np

from ..base import Observation
from ..groundtruth.legs import step_towards
from .ns import NaivePolicy


class FrontierPolicy(NaivePolicy):
    name = "frontier"

    def explore(self, obs: Observation) -> np.ndarray:
        h, w = self.cfg.height, self.cfg.width
        ys, xs = np.mgrid[0:h, 0:w]
        p = obs.positions
        d = np.abs(xs[None] - p[:, 0, None, None]) + np.abs(ys[None] - p[:, 1, None, None])
        key = np.where(self.visited, np.inf, d + self.rng.random(d.shape) * 0.5).reshape(len(d), -1)
        idx = key.argmin(axis=1)
        a = step_towards(p, np.stack([idx % w, idx // w], axis=1), self.rng)
        return np.where(np.isinf(key.min(axis=1)), 4, a)  # 4: nothing left, NS picks a valid move
