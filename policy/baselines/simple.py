"""Policies that need no learning: NS (the paper's naive solution), lawnmower, a
frontier-greedy explorer and random. All batched and seeded; they read only observations."""

from __future__ import annotations

import zlib

import numpy as np

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy, random_valid
from ..groundtruth.legs import step_towards
from ..loops import vote


class _Tracking(Policy):
    """Keeps a visited mask from positions, so it works with every map variant."""

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.cfg = cfg
        self.rng = np.random.default_rng([seed, zlib.crc32(self.name.encode())])
        self.visited = np.zeros((n, cfg.height, cfg.width), dtype=bool)
        self.rows = np.arange(n)

    def _see(self, obs: Observation) -> None:
        p = obs.positions
        self.visited[self.rows, p[:, 1], p[:, 0]] = True


class NaivePolicy(_Tracking):
    """NS: step towards an unvisited target in the 3 x 3 view (diagonal: either way at random);
    otherwise explore, for NS with the loop fallback's vote towards unvisited cells."""

    name = "ns"

    def explore(self, obs: Observation) -> np.ndarray:
        return vote(obs.positions, self.visited, self.rng)

    def act(self, obs: Observation) -> np.ndarray:
        self._see(obs)
        h, w = self.cfg.height, self.cfg.width
        tgt = obs.views[:, 0].astype(bool)  # (n, 3, 3), rows y-1..y+1
        dy, dx = np.meshgrid(np.arange(-1, 2), np.arange(-1, 2), indexing="ij")
        ys = np.clip(obs.positions[:, 1, None, None] + dy, 0, h - 1)
        xs = np.clip(obs.positions[:, 0, None, None] + dx, 0, w - 1)
        unvisited = tgt & ~self.visited[self.rows[:, None, None], ys, xs]
        seen = unvisited.any(axis=(1, 2))
        a = self.explore(obs)
        if seen.any():
            keys = unvisited[seen].reshape(-1, 9) + self.rng.random((int(seen.sum()), 9)) * 0.5
            cell = keys.argmax(axis=1)
            goal = obs.positions[seen] + np.stack([cell % 3 - 1, cell // 3 - 1], axis=1)
            a[seen] = step_towards(obs.positions[seen], goal, self.rng)
        stuck = a >= 4
        if stuck.any():
            a[stuck] = random_valid(obs.valid[stuck, :4], self.rng)
        return a


class FrontierPolicy(NaivePolicy):
    """NS's target rule, but exploring towards the nearest unvisited cell (Manhattan, ties at
    random) instead of by vote."""

    name = "frontier"

    def explore(self, obs: Observation) -> np.ndarray:
        h, w = self.cfg.height, self.cfg.width
        ys, xs = np.mgrid[0:h, 0:w]
        p = obs.positions
        d = np.abs(xs[None] - p[:, 0, None, None]) + np.abs(ys[None] - p[:, 1, None, None])
        key = np.where(self.visited, np.inf, d + self.rng.random(d.shape) * 0.5).reshape(len(d), -1)
        idx = key.argmin(axis=1)
        a = step_towards(p, np.stack([idx % w, idx // w], axis=1), self.rng)
        return np.where(np.isinf(key.min(axis=1)), 4, a)


def serpentine(w: int, h: int, corner: int) -> np.ndarray:
    """(w*h, 2) boustrophedon cells sweeping rows from one of the four corners."""
    cells = []
    for i, y in enumerate(range(h)):
        xs = range(w) if i % 2 == 0 else range(w - 1, -1, -1)
        cells += [(x, y) for x in xs]
    c = np.array(cells)
    if corner & 1:
        c[:, 0] = w - 1 - c[:, 0]
    if corner & 2:
        c[:, 1] = h - 1 - c[:, 1]
    return c


class LawnmowerPolicy(Policy):
    """Fly to the nearest corner, then sweep the rows: the survey pilot's default."""

    name = "lawnmower"

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.rng = np.random.default_rng([seed, 0x1A7])
        self.routes = np.stack([serpentine(cfg.width, cfg.height, c) for c in range(4)])  # (4, wh, 2)
        self.corner: np.ndarray | None = None
        self.idx = np.zeros(n, dtype=np.int64)
        self.cfg = cfg

    def act(self, obs: Observation) -> np.ndarray:
        p = obs.positions
        if self.corner is None:
            starts = self.routes[:, 0]  # (4, 2)
            d = np.abs(p[:, None, :] - starts[None]).sum(-1) + self.rng.random((len(p), 4)) * 0.5
            self.corner = d.argmin(axis=1)
        last = self.routes.shape[1] - 1
        for _ in range(2):  # advance past the waypoint we are standing on
            goal = self.routes[self.corner, np.minimum(self.idx, last)]
            here = np.all(goal == p, axis=1) & (self.idx < last)
            self.idx[here] += 1
        goal = self.routes[self.corner, np.minimum(self.idx, last)]
        a = step_towards(p, goal, self.rng)
        stuck = a >= 4
        if stuck.any():
            a[stuck] = random_valid(obs.valid[stuck, :4], self.rng)
        return a


class RandomPolicy(Policy):
    name = "random"

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.rng = np.random.default_rng([seed, 0x7A2D])
        self.n_actions = cfg.n_actions

    def act(self, obs: Observation) -> np.ndarray:
        return random_valid(obs.valid[:, : self.n_actions], self.rng)
