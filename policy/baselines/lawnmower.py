"""The survey pilot's default: fly to the nearest corner, then sweep the rows (boustrophedon).
On 10 x 10 it needs the corner distance plus up to 99 moves; the paper quotes >= 41 steps."""

from __future__ import annotations

import numpy as np

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy, random_valid
from ..groundtruth.legs import step_towards


def serpentine(w: int, h: int, corner: int) -> np.ndarray:
    """(w*h, 2) boustrophedon cells sweeping rows from corner 0 (top-left), 1 (top-right),
    2 (bottom-left) or 3 (bottom-right)."""
    xs = np.arange(w)
    rows = [xs if y % 2 == 0 else xs[::-1] for y in range(h)]
    c = np.stack([np.concatenate(rows), np.repeat(np.arange(h), w)], axis=1)
    if corner & 1:
        c[:, 0] = w - 1 - c[:, 0]
    if corner & 2:
        c[:, 1] = h - 1 - c[:, 1]
    return c


class LawnmowerPolicy(Policy):
    name = "lawnmower"

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.rng = np.random.default_rng([seed, 0x1A7])
        self.routes = np.stack([serpentine(cfg.width, cfg.height, c) for c in range(4)])  # (4, wh, 2)
        self.corner: np.ndarray | None = None
        self.idx = np.zeros(n, dtype=np.int64)

    def act(self, obs: Observation) -> np.ndarray:
        p = obs.positions
        if self.corner is None:  # nearest corner, ties at random
            starts = self.routes[:, 0]  # (4, 2)
            d = np.abs(p[:, None, :] - starts[None]).sum(-1) + self.rng.random((len(p), 4)) * 0.5
            self.corner = d.argmin(axis=1)
        last = self.routes.shape[1] - 1
        goal = self.routes[self.corner, self.idx]
        # standing on the current waypoint: the next one (consecutive waypoints are neighbours)
        here = np.all(goal == p, axis=1) & (self.idx < last)
        self.idx[here] += 1
        a = step_towards(p, self.routes[self.corner, self.idx], self.rng)
        stuck = a >= 4  # the sweep is over: any valid move until t_e
        if stuck.any():
            a[stuck] = random_valid(obs.valid[stuck, :4], self.rng)
        return a
