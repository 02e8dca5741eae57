"""NS, the paper's naive solution (Section V-D): step towards a visible unvisited target,
otherwise follow the loop fallback's vote towards unvisited cells. No loop detection of its
own (Table I has '-' in NS's loop columns): the vote is already its exploration rule."""

from __future__ import annotations

import zlib

import numpy as np

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy, random_valid
from ..groundtruth.legs import step_towards
from ..loops import vote

_OFF = np.arange(-1, 2)


class VisitTracking(Policy):
    """Keeps a visited mask from positions, so a policy works with every map variant
    (the spatiotemporal map forgets visits after 50 moves; the static maps hold the same mask)."""

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.cfg = cfg
        self.rng = np.random.default_rng([seed, zlib.crc32(self.name.encode())])
        self.visited = np.zeros((n, cfg.height, cfg.width), dtype=bool)
        self.rows = np.arange(n)
        self._masked = False

    def _see(self, obs: Observation) -> None:
        if obs.mask is not None and not getattr(self, "_masked", False):
            # a masked field: its masked cells count as visited, like off-map ones (nothing to find)
            self._masked = True
            self.visited |= ~np.asarray(obs.mask, bool)
        p = obs.positions
        self.visited[self.rows, p[:, 1], p[:, 0]] = True


class NaivePolicy(VisitTracking):
    """A target in the 3 x 3 view whose cell is unvisited has not been recovered: step towards
    it (diagonal: either way at random, Eq. 3). Otherwise `explore`, for NS the vote."""

    name = "ns"

    def explore(self, obs: Observation) -> np.ndarray:
        return vote(obs.positions, self.visited, self.rng)

    def act(self, obs: Observation) -> np.ndarray:
        self._see(obs)
        h, w = self.cfg.height, self.cfg.width
        tgt = obs.views[:, 0].astype(bool)  # (n, 3, 3), rows y-1..y+1, off-map cells never set
        if tgt.shape[1:] != (3, 3):  # altitude levels: NS flies at level 1, its 3 x 3 is the centre
            c = tgt.shape[1] // 2
            tgt = tgt[:, c - 1: c + 2, c - 1: c + 2]
        ys = np.clip(obs.positions[:, 1, None, None] + _OFF[None, :, None], 0, h - 1)
        xs = np.clip(obs.positions[:, 0, None, None] + _OFF[None, None, :], 0, w - 1)
        unvisited = tgt & ~self.visited[self.rows[:, None, None], ys, xs]
        seen = unvisited.any(axis=(1, 2))
        a = self.explore(obs)
        if seen.any():
            # several visible targets: one at random
            keys = unvisited[seen].reshape(-1, 9) + self.rng.random((int(seen.sum()), 9)) * 0.5
            cell = keys.argmax(axis=1)
            goal = obs.positions[seen] + np.stack([cell % 3 - 1, cell // 3 - 1], axis=1)
            if obs.mask is None:
                a[seen] = step_towards(obs.positions[seen], goal, self.rng)
            else:  # a diagonal target: the way round that stays on the field
                from ..groundtruth.masked import move_towards

                mask = np.asarray(obs.mask, bool)[seen]
                a[seen] = move_towards(mask, obs.positions[seen], goal, obs.valid[seen], self.rng)
        stuck = a >= 4  # nothing unvisited anywhere: any valid move
        if stuck.any():
            a[stuck] = random_valid(obs.valid[stuck, :4], self.rng)
        return a
