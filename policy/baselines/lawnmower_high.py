"""The operator's sweep from height (issue 27): climb to the level whose footprint tiles the
field in the fewest lanes (the highest), fly a boustrophedon of lanes spaced one footprint
apart, then descend and visit every cell believed occupied (the belief planner's close-up
tour over the soft-evidence belief, as an operator would check every detection), and search
on with the belief planner's rule if a target is still missing. The fixed-height baseline
that `belief` with levels is measured against."""

from __future__ import annotations

import numpy as np

from sim.gridworld import Action, Episodes, GridConfig

from ..base import Observation, Policy, random_valid
from ..groundtruth.legs import step_towards


def lane_route(cfg: GridConfig, level: int, corner: int) -> np.ndarray:
    """(k, 2) waypoints: lanes along y at x = r, r + (2r + 1), ... (the last one moved in to
    W - 1 - r so the footprint tiles the far border), each lane end to end, boustrophedon,
    starting from the corner 0 (top-left), 1 (top-right), 2 (bottom-left), 3 (bottom-right)."""
    r, w, h = level, cfg.width, cfg.height
    xs = list(range(min(r, w - 1), w, 2 * r + 1))
    if xs[-1] + r < w - 1:
        xs.append(max(w - 1 - r, 0))
    ys = [min(r, h - 1), max(h - 1 - r, 0)]
    pts = []
    for i, x in enumerate(xs):
        pts += [(x, ys[i % 2]), (x, ys[1 - i % 2])]
    c = np.array(pts, np.int64)
    if corner & 1:
        c[:, 0] = w - 1 - c[:, 0]
    if corner & 2:
        c[:, 1] = h - 1 - c[:, 1]
    return c


class HighLawnmowerPolicy(Policy):
    name = "lawnmower-high"

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        from ..planner import BeliefPlanner
        from ..planner.altitude import AltitudeParams

        self.cfg, self.n = cfg, n
        self.rng = np.random.default_rng([seed, 0x1A7E])
        self.level = cfg.levels
        self.routes = np.stack([lane_route(cfg, self.level, c) for c in range(4)])
        self.corner: np.ndarray | None = None
        self.idx = np.zeros(n, np.int64)
        self.surveying = np.ones(n, bool)
        # after the sweep: the belief planner's close-up tour of every detection (tour_below
        # = infinity: tour whenever a cell is believed occupied), its search rule otherwise
        self.after = BeliefPlanner(altitude=AltitudeParams(tour_below=float(cfg.n_targets) + 1.0))
        self.after.reset(cfg, n, seed + 1)

    def act(self, obs: Observation) -> np.ndarray:
        p = np.asarray(obs.positions)
        level = np.ones(self.n, np.int64) if obs.level is None else np.asarray(obs.level)
        after = self.after.act(obs)  # keeps the belief up to date on every move
        if self.corner is None:
            starts = self.routes[:, 0]
            d = np.abs(p[:, None, :] - starts[None]).sum(-1) + self.rng.random((len(p), 4)) * 0.5
            self.corner = d.argmin(axis=1)
        last = self.routes.shape[1] - 1
        goal = self.routes[self.corner, self.idx]
        here = np.all(goal == p, axis=1) & (level == self.level)
        self.surveying &= ~(here & (self.idx == last))  # the last lane flown: the sweep is over
        self.idx[here & (self.idx < last)] += 1
        goal = self.routes[self.corner, self.idx]
        a = after.copy()
        s = self.surveying
        if s.any():
            climb = s & (level < self.level)
            move = s & ~climb
            a[climb] = Action.CLIMB
            if move.any():
                a[move] = step_towards(p[move], goal[move], self.rng)
        valid = np.asarray(obs.valid)
        bad = ~valid[np.arange(self.n), np.minimum(a, valid.shape[1] - 1)]
        if bad.any():
            a[bad] = random_valid(valid[bad], self.rng)
        return a


__all__ = ["HighLawnmowerPolicy", "lane_route"]
