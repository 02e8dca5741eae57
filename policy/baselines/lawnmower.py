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
        if obs.mask is not None:
            return self._act_masked(obs)
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

    # ------------------------------------------------------------------ masked fields
    def _act_masked(self, obs: Observation) -> np.ndarray:
        """The sweep on a masked field: the boustrophedon over the searchable cells only, row by
        row (the grid is laid along the field's heading, so rows are the polygon's strips),
        skipping masked cells and cells already flown over, each transition a shortest path
        around the holes (BFS). The corner: the route whose first cell is nearest."""
        from sim.gridworld.masks import UNREACHABLE, distance_fields

        from ..groundtruth.masked import move_towards

        mask, p = np.asarray(obs.mask, bool), obs.positions
        n, h, w = mask.shape
        rows = np.arange(n)
        if self.corner is None:
            self._visited = np.zeros((n, h, w), bool)
            full = self.routes  # (4, wh, 2)
            on = mask[:, full[..., 1], full[..., 0]]  # (n, 4, wh): route cells that are searchable
            # each episode's 4 routes: the searchable cells in sweep order, first, padded with -1
            rank = np.argsort(~on, axis=2, kind="stable")
            cells = full[np.arange(4)[None, :, None], rank]  # (n, 4, wh, 2)
            self._len = on.sum(axis=2)  # (n, 4)
            self._route_all = np.where((np.arange(h * w)[None, None, :] < self._len[..., None])[..., None], cells, -1)
            d = distance_fields(mask, p).astype(np.float64)
            first = self._route_all[:, :, 0]  # (n, 4, 2)
            dist = d[rows[:, None], first[..., 1], first[..., 0]]
            dist[dist >= UNREACHABLE] = np.inf
            self.corner = (dist + self.rng.random((n, 4)) * 0.5).argmin(axis=1)
        self._visited[rows, p[:, 1], p[:, 0]] = True
        route = self._route_all[rows, self.corner]  # (n, wh, 2)
        length = self._len[rows, self.corner]
        k = np.arange(route.shape[1])[None]
        seen = self._visited[rows[:, None], np.clip(route[..., 1], 0, h - 1), np.clip(route[..., 0], 0, w - 1)]
        todo = (k < length[:, None]) & ~seen
        left = todo.any(axis=1)
        self.idx = np.where(left, todo.argmax(axis=1), self.idx)
        goal = np.where(left[:, None], route[rows, self.idx], p)
        a = move_towards(mask, p, goal, obs.valid, self.rng)
        stuck = ~left | (a >= 4)  # the sweep is over: any valid move until t_e
        if stuck.any():
            a[stuck] = random_valid(obs.valid[stuck, :4], self.rng)
        return a
