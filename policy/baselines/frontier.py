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
        if obs.mask is not None:  # BFS distances around the holes, and a move along them
            return self._explore_masked(obs)
        d = np.abs(xs[None] - p[:, 0, None, None]) + np.abs(ys[None] - p[:, 1, None, None])
        key = np.where(self.visited, np.inf, d + self.rng.random(d.shape) * 0.5).reshape(len(d), -1)
        idx = key.argmin(axis=1)
        a = step_towards(p, np.stack([idx % w, idx // w], axis=1), self.rng)
        return np.where(np.isinf(key.min(axis=1)), 4, a)  # 4: nothing left, NS picks a valid move

    def _explore_masked(self, obs: Observation) -> np.ndarray:
        from sim.gridworld.masks import UNREACHABLE, distance_fields

        from ..groundtruth.masked import move_towards

        w = self.cfg.width
        mask, p = np.asarray(obs.mask, bool), obs.positions
        d = distance_fields(mask, p).astype(np.float64)
        d[d >= UNREACHABLE] = np.inf
        key = np.where(self.visited, np.inf, d + self.rng.random(d.shape) * 0.5).reshape(len(d), -1)
        idx = key.argmin(axis=1)
        none = np.isinf(key.min(axis=1))
        goal = np.where(none[:, None], p, np.stack([idx % w, idx // w], axis=1))
        a = move_towards(mask, p, goal, obs.valid, self.rng)
        return np.where(none, 4, a)  # 4: nothing left, NS picks a valid move
