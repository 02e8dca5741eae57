"""`belief`: a non-learned belief-space planner, batched over episodes.

It sees only what the drone sees (the 3 x 3 view, its position or the GPS posterior) and the
placement prior (given, or estimated from data), through policy.belief.BeliefState:

- Static targets, every target sighted (the belief's never-sighted mass is 0): the exact
  shortest tour through the sighted, not-found targets (Held-Karp, policy.groundtruth), computed
  once when an episode gets there and then followed: a suffix of an optimal path is optimal,
  and nothing new can be learned, so it is never recomputed.
- Otherwise: go towards the goal cell g maximising

      value(g) = (reveal(g) + pickup * target(g)) / (distance(g) + travel_offset)

  reveal(g): the expected never-sighted targets that standing on g would show (the prior-weighted
  unseen mass of g's 3 x 3 window, plus `outer` times that of the ring around it, which steers
  towards unexplored regions rather than single leftover cells); target(g): the believed
  unfound targets on g itself (1 for a sighted static target), which standing there recovers.
  Information (targets revealed or recovered) per step of travel: the issue's rule, with the
  travel offset making a far rich cell compete with a near poor one. Among the shortest-path
  first moves towards g it takes the one whose next view reveals more.
- Moving targets: the same rule on the diffused unfound density, with the ring weighted the
  same way (a sighted target is a blob that grows while nobody looks). Given a pair
  correlation (the herd starts as a lattice and deviates 10 % of its moves), where to look is
  weighted towards the found targets by that correlation blurred over 5 x 5 cells.
- Masked fields, static targets (issue 28): distances are path lengths around the holes, and
  two terms keep the greedy rule from leaving parts of the field behind and coming back for
  them (on a field at an angle to the grid its staircase edges and arms made it do so, +9 %
  over its rectangle ratio): an unseen cell is worth more the more of its 5 x 5 window is
  seen already (a pocket passed by costs a return trip later; `pocket`), and a goal's value
  is weighted by how outlying it is from the unseen mass (`spread`: the smaller side of a
  branch before the larger). Without a mask neither applies: the rectangle plans as before.

Every quantity is a whole-batch array; the only Python loops are over the 9 view slots, the
4 moves and (once per episode) the tour's Held-Karp groups.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.gridworld import DELTAS, Episodes, GridConfig

from ..base import Observation, Policy, random_valid
from ..belief import BeliefState
from ..belief.state import weighted_rows
from ..groundtruth.legs import step_towards
from ..groundtruth.pt import held_karp
from .altitude import AltitudeParams, AltitudeRule


@dataclass(frozen=True)
class PlannerParams:
    """The rule's weights (tuned on training seeds, never on the test seeds; docs/search.md)."""

    pickup: float = 3.0
    outer: float = 0.1
    travel_offset: float = 0.5
    #: weight of the immediate reveal when choosing among equally short first moves
    tie_reveal: float = 1.0
    #: unseen cells that few positions can see (borders: 6 of 9, corners: 4) are worth
    #: (9 / viewers) ** edge: left for later they cost a pass of their own
    edge: float = 1.0
    #: moving targets with a pair correlation: weight of "the others are near the found ones"
    #: (the blurred pair correlation, as a log-factor on where to look); 0.5 took herd from
    #: 39.7 to 37.5 moves on the tuning seeds
    herd: float = 0.5
    #: under an uncertain position (obs.position_prob), plan from the belief's likeliest cell
    #: (the posterior after the view's evidence) where it is at least this likely and not the
    #: cell the agent was told (obs.positions); 1 or more: always from the told cell
    plan_from_belief: float = 0.5
    #: masked fields, static targets only (issue 28; none of the three touches a rectangle):
    #: an unseen cell's weight times (1 + pocket * its isolation), the share of the searchable
    #: cells of its 5 x 5 window already seen: a pocket the agent passes by costs a return
    #: trip of its own later, so it is worth more while it is near
    pocket: float = 1.0
    #: masked fields, static targets: a goal's value times its periphery ** spread, its mean
    #: distance to the unseen mass over that mass's mean (the outlying parts first: where a
    #: field branches, the smaller side before the larger one, so nothing is left at the end of
    #: an arm to come back for). Together (with mask_travel_offset 1) on 1000 fields, seed 2,
    #: ratio over the rectangle's: rotated L +8.6 % -> +3.8 %, rotated holes +8.7 % -> +5.5 %,
    #: rotated convex +5.3 % -> +3.4 %, aligned convex +5.4 % -> +3.4 %
    #: (benchmarks/masked_belief_moves.py; docs/fields.md)
    spread: float = 0.5
    #: travel_offset on a masked field with static targets (1: a near goal weighs less against
    #: a far one than with 0.5, which suits the pocket term)
    mask_travel_offset: float = 1.0

    def __post_init__(self) -> None:
        for k in ("pickup", "outer", "travel_offset", "edge", "herd", "plan_from_belief", "pocket", "spread",
                  "mask_travel_offset"):
            if not getattr(self, k) >= 0:
                raise ValueError(f"PlannerParams.{k} must be >= 0 (got {getattr(self, k)})")


def _window(a: np.ndarray, radius: int, work: dict | None = None) -> np.ndarray:
    """Sum of a (n, h, w) over the (2r+1)^2 window centred on each cell (zero outside).

    The shifted copies (_shift(a, dy, dx)) are added in the same order as ever, so the sums
    (and the planner's decisions) are the same bit for bit; but they are read from one
    zero-padded copy of a, flattened: shifting by (dy, dx) is then an offset of dy * W + dx in
    one contiguous run, and each addition is one contiguous (vectorised) pass instead of a
    fresh shifted array. Cells of the padding pick up neighbouring rows' values and are dropped.
    work: a dict to keep the two padded buffers in between calls (fresh large arrays cost page
    faults on every call); their borders are never written, so they stay zero."""
    h, w = a.shape[-2:]
    r = radius
    hp, wp = h + 2 * r, w + 2 * r
    key = (a.shape, a.dtype.str, r)
    if work is None or key not in work:
        bufs = (np.zeros(a.shape[:-2] + (hp, wp), a.dtype), np.empty(a.size // (h * w) * hp * wp, a.dtype))
        if work is not None:
            work[key] = bufs
    else:
        bufs = work[key]
    padded, acc = bufs
    padded[..., r: r + h, r: r + w] = a
    flat = padded.reshape(-1)
    acc.fill(0.0)
    lo, hi = r * wp + r, flat.size - (r * wp + r)  # every kept cell's flat index lies in [lo, hi)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            off = dy * wp + dx  # out[y, x] += a[y - dy, x - dx]
            acc[lo:hi] += flat[lo - off: hi - off]
    return acc.reshape(padded.shape)[..., r: r + h, r: r + w].copy()


def resolve_prior(prior: Any, cfg: GridConfig) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(placement density, pair correlation) from: None (uniform, independent), an (h, w)
    array (density only), Episodes (both counted from their targets at t = 0), 'model' (the
    config's own placement model, sampled) or a dataset path (both estimated from its samples)."""
    from ..belief import estimate_pair, estimate_prior, model_pair, model_prior

    if prior is None:
        return None, None
    if isinstance(prior, np.ndarray):
        return prior, None
    if isinstance(prior, Episodes):  # e.g. training episodes: both counted from their targets
        return estimate_prior(prior, cfg), (estimate_pair(prior, cfg) if cfg.n_targets > 1 else None)
    if isinstance(prior, str) and prior == "model":
        return model_prior(cfg), model_pair(cfg)
    if isinstance(prior, str | Path):
        path = Path(prior)
        density = estimate_prior(path, cfg)
        try:
            pair = estimate_pair(path, cfg) if cfg.n_targets > 1 else None
        except ValueError:  # no episode of the dataset met every target (moving targets)
            pair = None
        return density, pair
    raise ValueError(f"prior must be None, an (h, w) array, 'model' or a dataset path (got {prior!r})")


class BeliefPlanner(Policy):
    name = "belief"

    def __init__(self, prior: Any = None, params: PlannerParams | None = None,
                 altitude: AltitudeParams | None = None) -> None:
        """altitude: the weights of the rule over (cell, level) where cfg.levels > 1
        (policy.planner.altitude); levels = 1 plans as before."""
        self.prior_spec = prior
        self.params = params or PlannerParams()
        self.altitude = altitude or AltitudeParams()
        self._prior_cache: dict[tuple, tuple[np.ndarray | None, np.ndarray | None]] = {}

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        key = (cfg.width, cfg.height, cfg.distribution, cfg.n_targets)
        if key not in self._prior_cache:
            self._prior_cache[key] = resolve_prior(self.prior_spec, cfg)
        self.cfg, self.n = cfg, n
        density, pair = self._prior_cache[key]
        self.belief = BeliefState(cfg, n, density, pair)
        self._herd = None
        if cfg.moving and pair is not None:
            # moving targets keep their placement's structure only loosely (a herd deviates
            # 10 % of its moves): the pair correlation blurred by two cells says "the others are
            # near the ones seen", and weights where the planner looks, not the belief itself
            from scipy.ndimage import uniform_filter

            g = uniform_filter(np.log(np.clip(pair, 1e-3, None)), size=5, mode="nearest")
            h, w = cfg.height, cfg.width
            cy, cx = np.divmod(np.arange(h * w), w)
            self._herd = g[cy[None, :] - cy[:, None] + h - 1, cx[None, :] - cx[:, None] + w - 1].astype(np.float32)
        self.rng = np.random.default_rng([seed, 0xBE11EF])
        self._work: dict = {}  # _window's buffers
        self.rows = np.arange(n)
        h, w = cfg.height, cfg.width
        self.ys, self.xs = np.mgrid[0:h, 0:w]
        viewers = _window(np.ones((1, h, w)), 1)[0]
        self.cell_weight = (9.0 / viewers) ** self.params.edge
        # the tour, once every target is sighted (static): cells in order, -1 padded
        self.tour = np.full((n, cfg.n_targets, 2), -1, np.int64)
        self.tour_len = np.zeros(n, np.int64)
        self.in_tour = np.zeros(n, bool)
        #: where the view is a sample of detections (altitude levels): the (cell, level) rule
        self._alt: AltitudeRule | None = None
        if not cfg.perfect_detection:
            self._alt = AltitudeRule(cfg, n, self.rng, self.altitude, lambda a, r: _window(a, r, self._work))
        #: (n, h, w) bool searchable cells once an observation brings a mask (obs.mask), else None
        self.mask: np.ndarray | None = None
        self._pair = pair

    def _adopt_mask(self, mask: np.ndarray) -> None:
        """A masked field (obs.mask, at the first decision): the belief's prior lives on the
        searchable cells, distances are BFS distances around the holes (sim.gridworld.masks),
        and a cell's edge weight counts the searchable cells it can be seen from."""
        from sim.gridworld.masks import episode_masks

        cfg, n = self.cfg, self.n
        self.mask = episode_masks(np.asarray(mask, bool), n, cfg.height, cfg.width)
        density = self._prior_cache[(cfg.width, cfg.height, cfg.distribution, cfg.n_targets)][0]
        self.belief = BeliefState(cfg, n, density, self._pair, mask=self.mask)
        viewers = _window(self.mask.astype(np.float64), 1)
        self.cell_weight = np.where(viewers > 0, (9.0 / np.maximum(viewers, 1.0)) ** self.params.edge, 0.0)
        #: the searchable cells of each cell's 5 x 5 window (the pocket term's denominator)
        self._field5 = np.maximum(_window(self.mask.astype(np.float64), 2), 1.0)

    @property
    def _shaped(self) -> bool:
        """Whether the masked-field terms (pocket, spread, mask_travel_offset) apply: a mask,
        static targets (what they were tuned on; moving targets plan as before)."""
        return self.mask is not None and not self.cfg.moving

    # ------------------------------------------------------------------------ the rule
    def _reveal(self) -> np.ndarray:
        """(n, h, w) expected never-sighted targets a view from each cell would show."""
        b, p = self.belief, self.params
        if self.cfg.moving:
            mass = b.target * 1.0
            if self._herd is not None:
                logf = weighted_rows(b.found.reshape(self.n, -1), self._herd).reshape(mass.shape)
                wgt = np.exp(self.params.herd * (logf - logf.max(axis=(1, 2), keepdims=True)))
                tot = mass.sum(axis=(1, 2), keepdims=True)
                mass = mass * wgt
                mass *= tot / np.maximum(mass.sum(axis=(1, 2), keepdims=True), 1e-9)
        else:
            mass = b.target - b.sighted  # the prior-spread pool over unseen cells
        mass = mass * self.cell_weight
        if self._shaped and p.pocket > 0:
            seen = _window((b.seen * self.mask).astype(np.float64), 2, self._work)
            mass = mass * (1.0 + p.pocket * np.clip(seen / self._field5, 0.0, 1.0))
        self._mass = mass
        near = _window(mass, 1, self._work)
        if p.outer > 0:
            near = near + p.outer * (_window(mass, 2, self._work) - near)
        return near

    @staticmethod
    def _periphery(mass: np.ndarray) -> np.ndarray:
        """(n, h, w) each cell's mean Manhattan distance to the (weighted) unseen mass, over that
        mass's own mean distance to itself: above 1 on the outlying parts of what is left. From
        the mass's row and column sums, so O(cells) (no all-pairs table); Manhattan, not the
        path length around holes (that, from landmark BFS fields, did no better)."""
        n, h, w = mass.shape
        tot = np.maximum(mass.sum(axis=(1, 2)), 1e-12)
        ax, ay = np.arange(w), np.arange(h)
        fx = mass.sum(axis=1) @ np.abs(ax[:, None] - ax[None, :]).astype(np.float64)  # (n, w)
        fy = mass.sum(axis=2) @ np.abs(ay[:, None] - ay[None, :]).astype(np.float64)  # (n, h)
        phi = (fx[:, None, :] + fy[:, :, None]) / tot[:, None, None]
        mean = (phi * mass).sum(axis=(1, 2)) / tot
        return phi / np.maximum(mean, 1e-9)[:, None, None]

    def _goal(self, pos: np.ndarray) -> np.ndarray:
        b, p = self.belief, self.params
        reveal = self._reveal()
        self._reveal_map = reveal
        pick = b.sighted if not self.cfg.moving else b.target
        if self.mask is not None:  # path lengths around the holes
            from sim.gridworld.masks import UNREACHABLE, distance_fields

            dm = distance_fields(self.mask, pos)
            d = dm.astype(np.float64)
        else:
            d = np.abs(self.xs[None] - pos[:, 0, None, None]) + np.abs(self.ys[None] - pos[:, 1, None, None])
        if self._shaped:
            value = (reveal + p.pickup * pick) / (d + p.mask_travel_offset)
            if p.spread > 0:
                value = value * self._periphery(self._mass) ** p.spread
        else:
            value = (reveal + p.pickup * pick) / (d + p.travel_offset)
        value = value + self.rng.random(value.shape) * 1e-6  # ties at random
        if self.mask is not None:
            value[dm >= UNREACHABLE] = -1.0  # masked or cut off: never a goal
        value[self.rows, pos[:, 1], pos[:, 0]] = -1.0  # standing still recovers nothing new
        idx = value.reshape(self.n, -1).argmax(axis=1)
        w = self.cfg.width
        return np.stack([idx % w, idx // w], axis=1)

    def _first_move(self, pos: np.ndarray, goal: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """A shortest-path move towards goal, preferring the one whose next view reveals more."""
        if self.mask is not None:
            return self._first_move_masked(pos, goal, valid)
        d0 = np.abs(goal - pos).sum(axis=1)
        nxt = pos[:, None, :] + DELTAS[None, :4]  # (n, 4, 2)
        d1 = np.abs(goal[:, None, :] - nxt).sum(axis=2)
        closer = (d1 < d0[:, None]) & valid[:, :4]
        h, w = self.cfg.height, self.cfg.width
        cx, cy = np.clip(nxt[..., 0], 0, w - 1), np.clip(nxt[..., 1], 0, h - 1)
        gain = self._reveal_map[self.rows[:, None], cy, cx]
        key = np.where(closer, self.params.tie_reveal * gain + self.rng.random(gain.shape) * 1e-6, -np.inf)
        a = key.argmax(axis=1)
        none = ~closer.any(axis=1)
        if none.any():  # at the goal already (should not happen): Eq. 3's move
            a[none] = step_towards(pos[none], goal[none], self.rng)
        return a

    def _first_move_masked(self, pos: np.ndarray, goal: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """_first_move on a masked field: the moves that shorten the path (the goal's BFS
        distance field), the one whose next view reveals more first."""
        from sim.gridworld.masks import distance_fields, step_along

        h, w = self.cfg.height, self.cfg.width
        nxt = pos[:, None, :] + DELTAS[None, :4]
        cx, cy = np.clip(nxt[..., 0], 0, w - 1), np.clip(nxt[..., 1], 0, h - 1)
        gain = self.params.tie_reveal * self._reveal_map[self.rows[:, None], cy, cx]
        a = step_along(distance_fields(self.mask, goal), pos, valid, self.rng, prefer=gain)
        none = a < 0
        if none.any():  # at the goal already, or cut off from it: any valid move
            a[none] = random_valid(valid[none, :4], self.rng)
        return a

    # ------------------------------------------------------------------------ the tour
    def _start_tours(self, rows: np.ndarray, pos: np.ndarray) -> None:
        sighted = self.belief.sighted[rows] > 0.5
        counts = sighted.sum(axis=(1, 2))
        for k in np.unique(counts):
            sel = rows[counts == k]
            if k == 0:
                self.tour_len[sel] = 0
                continue
            cells = np.argwhere(self.belief.sighted[sel] > 0.5)  # (m*k, 3) rows sorted by episode
            xy = np.stack([cells[:, 2], cells[:, 1]], axis=1).reshape(len(sel), k, 2)
            if self.mask is not None:  # the tour on path lengths around the holes
                from ..groundtruth.masked import held_karp_masked

                _, order = held_karp_masked(pos[np.searchsorted(rows, sel)], xy, self.mask[sel], self.rng)
            else:
                _, order = held_karp(pos[np.searchsorted(rows, sel)], xy, self.rng)
            self.tour[sel, :k] = np.take_along_axis(xy, order[..., None], axis=1)
            self.tour_len[sel] = k
        self.in_tour[rows] = True

    def _leave_spent_tours(self, active: np.ndarray) -> None:
        """A tour whose premise failed is left, and the search goes on: no tour cell holds a
        sighted target any more, or targets are believed unsighted again. Never in the grid
        world (every target sighted means every tour cell holds one until the last is found);
        in a flight one cow read twice (a near end at the frame's edge taken for a neighbour,
        then weighed one or two cells out) made every target seem sighted, the tour found the
        one cow and then stepped between its cells for 275 moves (flight seed 70). Episodes
        that have ended are left alone (their moves draw on the shared random stream)."""
        rows = self.rows[self.in_tour & (self.tour_len > 0) & active]
        if not len(rows):
            return
        b = self.belief
        cells = self.tour[rows]
        live = np.arange(self.cfg.n_targets)[None] < self.tour_len[rows, None]
        cx, cy = np.clip(cells[..., 0], 0, None), np.clip(cells[..., 1], 0, None)
        live &= b.sighted[rows[:, None], cy, cx] > 0.5
        spent = ~live.any(axis=1) | (b.unsighted[rows] > 0.5)
        self.in_tour[rows[spent]] = False

    def _tour_goal(self, rows: np.ndarray) -> np.ndarray:
        """The first tour cell still holding a sighted target (visited ones are found)."""
        b = self.belief
        cells = self.tour[rows]  # (m, R, 2)
        k = np.arange(self.cfg.n_targets)[None]
        live = k < self.tour_len[rows, None]
        cx, cy = np.clip(cells[..., 0], 0, None), np.clip(cells[..., 1], 0, None)
        live &= b.sighted[rows[:, None], cy, cx] > 0.5
        first = np.where(live.any(axis=1), live.argmax(axis=1), 0)
        return cells[np.arange(len(rows)), first]

    def _where(self, told: np.ndarray) -> np.ndarray:
        """The cells to plan from under an uncertain position: the belief's likeliest (its
        position posterior after the view's evidence, `BeliefState._position`) where it is at
        least plan_from_belief likely, else the cell the agent was told. Why: the view says where
        the agent is when it shows known targets (the belief weighs positions by it), and the
        told cell can be a row off for minutes (GPS bias, the frame registered on the wrong
        lattice point): planned from the told cell, a cow in view a cell north was taken to be
        under the agent, which "standing still recovers nothing" sent back and forth between
        two cells beside it for 8 moves (flight seed 58)."""
        q = self.belief.position.reshape(self.n, -1)
        best = q.argmax(axis=1)
        sure = q[self.rows, best] >= self.params.plan_from_belief
        w = self.cfg.width
        return np.where(sure[:, None], np.stack([best % w, best // w], axis=1), told).astype(np.int64)

    # ------------------------------------------------------------------------ act
    def act(self, obs: Observation) -> np.ndarray:
        if obs.mask is not None and self.mask is None:
            self._adopt_mask(obs.mask)
        self.belief.update(obs)
        if self._alt is not None:
            return self._alt.act(self.belief, obs)
        pos = np.asarray(obs.positions, dtype=np.int64)
        if obs.position_prob is not None:
            pos = self._where(pos)
        valid = np.asarray(obs.valid)
        goal = self._goal(pos)
        if not self.cfg.moving and obs.position_prob is None:
            self._leave_spent_tours(np.asarray(obs.active, bool))
            ready = (self.belief.unsighted < 1e-6) & ~self.in_tour & np.asarray(obs.active, bool)
            if ready.any():
                self._start_tours(self.rows[ready], pos[ready])
            touring = self.in_tour & (self.tour_len > 0)
            if touring.any():
                tr = self.rows[touring]
                goal[tr] = self._tour_goal(tr)
        a = self._first_move(pos, goal, valid)
        bad = (a >= valid.shape[1]) | ~valid[self.rows, np.minimum(a, valid.shape[1] - 1)]
        if bad.any():
            a[bad] = random_valid(valid[bad, :4], self.rng)
        return a
