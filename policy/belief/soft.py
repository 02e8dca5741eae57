"""Soft evidence: the belief's update where the view is a sample of detections, not the truth
(altitude levels, sim.gridworld.detection; docs/altitude.md).

Per cell the belief holds two expected counts, unfound u and found f (at most one target a
cell, so o = u + f is the probability the cell is occupied). A look at a cell from level l at
ring k (Chebyshev distance from the nadir cell) detects a target with p = p_d(l, k) and
raises a false alarm on an empty cell with a = false_alarm_per_cell(l):

    detection: o' = o p / (o p + (1 - o) a)
    miss:      o' = o (1 - p) / (o (1 - p) + (1 - o) (1 - a))

and both populations keep their shares of o (u' = u o' / o, f' = f o' / o): a sighting of a
cell that holds a found target is that found target. Then the agent's own cell at level 1:
any unfound target there has just been recovered (the world's rule), so u = 0 there, and a
find (obs.found_now) puts a found target there. Last, the populations are rescaled to their
known sizes (R - n_found unfound; n_found found, for moving targets), each cell capped at one
target: the known-cardinality renormalisation the perfect-view belief does, on soft evidence.

With p = 1 and a = 0 a look sets o to 0 or 1, and the rescaling spreads the remaining
unfound targets over the cells never seen in proportion to the placement prior: the
perfect-view belief's numbers (tested against it to float tolerance).
"""

from __future__ import annotations

import numpy as np

from sim.gridworld import GridConfig

#: cells at or above this occupancy (less a hair) take no more mass when the belief rescales
_FULL = 1.0 - 1e-6
#: the occupancy a sighted cell believed empty starts its update from (look)
REVIVE = 1e-4
#: share of the unfound total the free cells keep when the cells believed occupied seem to
#: hold it all (one of them may be a false alarm): the mass never vanishes from the rest
LEAK = 1e-3


class SoftView:
    """The detection model of one GridConfig, laid out for the batched update: every slot of
    the highest level's (2R + 1)^2 window, its ring and p_d per level."""

    def __init__(self, cfg: GridConfig) -> None:
        table = cfg.detection
        if table is None:  # levels == 1, perfect: only reached by tests that force soft mode
            from sim.gridworld import DetectionTable

            table = DetectionTable.perfect(cfg.levels)
        self.cfg = cfg
        self.radius = cfg.view_radius
        off = np.arange(-self.radius, self.radius + 1)
        self.dy = np.repeat(off, len(off))  # row-major slots, like views[:, :, dy + R, dx + R]
        self.dx = np.tile(off, len(off))
        self.ring = np.maximum(np.abs(self.dy), np.abs(self.dx))
        p, fa = table.ring_table(cfg.levels)
        self.p = np.array([[0.0] * (self.radius + 1)] + p)  # (L + 1, R + 1), row 0 unused
        self.fa = np.array([0.0] + fa)
        #: with false alarms a cell believed occupied may be empty: the rest keeps some mass
        self.leak = LEAK if any(v > 0 for v in fa) else 0.0

    @property
    def width(self) -> int:
        return 2 * self.radius + 1

    def cells(self, positions: np.ndarray, level: np.ndarray) -> tuple[tuple[np.ndarray, ...], np.ndarray,
                                                                        np.ndarray, np.ndarray]:
        """The cells in each agent's footprint: (index arrays (episode, y, x), slot index,
        p_d and false-alarm rate there), all flat over (episode, slot) pairs in view."""
        h, w = self.cfg.height, self.cfg.width
        n = len(positions)
        ys = positions[:, 1, None] + self.dy  # (n, K)
        xs = positions[:, 0, None] + self.dx
        ok = (ys >= 0) & (ys < h) & (xs >= 0) & (xs < w) & (self.ring[None] <= level[:, None])
        ep = np.broadcast_to(np.arange(n)[:, None], ok.shape)[ok]
        slot = np.broadcast_to(np.arange(len(self.dy))[None], ok.shape)[ok]
        lvl = level[ep]
        return (ep, ys[ok], xs[ok]), slot, self.p[lvl, self.ring[slot]], self.fa[lvl]


def look(u: np.ndarray, f: np.ndarray, detected: np.ndarray, p: np.ndarray,
         fa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Bayes update of the cells looked at (flat arrays): new (u, f). A detection of a
    cell believed empty lifts it from REVIVE: the belief's zeros can be approximations (the
    rescale's), and a sighting without false alarms says a target is there. A miss the model
    rules out (p = 1 on a surely occupied cell) leaves the cell as it was."""
    u = np.where(detected & (u + f < REVIVE), np.maximum(u, REVIVE), u)
    o = np.clip(u.astype(np.float64) + f, 0.0, 1.0)
    like_occ = np.where(detected, p, 1.0 - p)
    like_empty = np.where(detected, fa, 1.0 - fa)
    num = o * like_occ
    den = num + (1.0 - o) * like_empty
    post = np.where(den > 0, num / np.maximum(den, 1e-300), o)
    scale = np.where(o > 0, post / np.maximum(o, 1e-300), 0.0)
    return u * scale, f * scale


def fill(a: np.ndarray, total: np.ndarray, cap: np.ndarray, rounds: int = 6, leak: float = 0.0) -> np.ndarray:
    """a (n, h, w) >= 0 rescaled per episode so that it sums to total (n,), no cell above cap
    (n, h, w): the free cells are scaled alike, those that reach the cap stay there (a few
    rounds of water-filling), keeping at least `leak` of the total in the free cells (LEAK
    where false alarms exist: a cell believed occupied may be one). A row with no free mass is
    left as it is; a total above what the caps hold fills them."""
    a = np.minimum(a.astype(np.float64), cap)
    total = np.asarray(total, np.float64)[:, None, None]
    for _ in range(rounds):
        full = a >= cap * _FULL
        fixed = np.where(full, a, 0.0).sum(axis=(1, 2), keepdims=True)
        free = np.where(full, 0.0, a).sum(axis=(1, 2), keepdims=True)
        k = np.where(free > 1e-12, np.maximum(total - fixed, leak * total) / np.maximum(free, 1e-12), 1.0)
        if np.all(np.abs(k - 1.0) < 1e-9):
            break
        a = np.where(full, a, np.minimum(a * k, cap))
    have = a.sum(axis=(1, 2), keepdims=True)
    return np.where(have > total + 1e-9, a * (total / np.maximum(have, 1e-12)), a)  # more held than there is
