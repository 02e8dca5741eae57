"""The belief state: what the drone knows about the search, from its observations only.

One module, used by the belief planner, the learned search network, the evaluation and the
flight alike. Everything is batched over n episodes of one GridConfig: every array carries a
leading episode axis and every update is a handful of whole-array numpy operations (the 3 x 3
view is handled as 9 shifted copies of the position distribution, never a per-episode loop).

What it tracks, per cell:
- visited: P(the agent has stood on the cell). With an exact position, 0/1.
- seen:    P(the 3 x 3 view has shown the cell at least once).
- target:  expected number of NOT-yet-found targets in the cell now.
- found:   expected number of already-found targets in the cell now (moving targets keep
           moving after they are found, and the view shows them like any other).
- age:     expected moves since the view last showed the cell (how stale `seen` is).
- position: the agent's cell distribution (one-hot, or the GPS posterior obs.position_prob).
and n_found (n,): the believed number of targets found so far.

The model (why it is built this way):
- Observation. The view shows, for each of its 9 slots d, whether a target stands at
  (agent + d) now. With the agent at q with probability p(q), cell c is shown in slot d with
  probability p(c - d); the update is the expectation over q of the exact (known-position)
  update, so with an exact position it is exact, and under GPS noise it is the
  probabilistic version of the same thing (like autopilot_bridge's probabilistic map, which
  spreads a visit over the posterior). The view's off-map channel also tells where the agent
  can be (at a border or not): p is first conditioned on agreeing with it, and on its target
  channel (view_evidence): each slot showing a target counts the belief's P(a target is in
  the cell it would show), each empty slot 1 - that (floored at VIEW_EPS, the view can be
  wrong). A view that shows known targets where they are says where the agent is.
- A target shown in the agent's own cell has been found (the world recovers a target when
  the agent stands on its cell at the same time, and the observation comes after that move).
  Whether that was a new find the spatiotemporal map M tells (its recoveries channel is
  written at the agent's cell in the step of a find): then n_found is exact. With the other
  maps the belief counts the expected new finds, target / (target + found) in that cell.
- Found or not? The view shows targets whether found or not. A target shown in another
  cell is attributed to the unfound and found populations in proportion to their expected
  counts there: P(unfound) = target / (target + found), and 1 when both are 0 (a target
  nobody expected is new). For static targets this is exact: a sighted target is found iff
  its cell was visited (found = 1 exactly there, target = 0). For moving targets it is the
  Bayes rule for one target in a cell whose occupant is either population, with each
  population's density treated as independent per cell: a found target that wanders back
  into view near where it was found is recognised as found, a sighting far from every found
  target's reachable area counts as new.
- Targets sighted beyond the view (static only; obs.far_targets, the flight's: a real
  camera's frame edge shows the near end of a target one or two cells out): each sighting is
  a likelihood over cells, placed by Bayes over where targets can be (unfound + found,
  floored at FAR_EPS: a cell the view showed empty from a camera a metre off may hold it),
  and its unfound share raises the sighted mass there (max, so a target sighted again adds
  nothing); the grid world's view never has them.
- Static targets: the unfound mass is the sighted-not-found targets (1 in their cells) plus
  the never-sighted ones, R - n_found - sighted, spread over the cells not yet seen in
  proportion to the placement prior (exact for the random placement, where the posterior of
  the unseen cells is uniform; the marginal approximation for the others).
- Moving targets: both densities are diffused by the motion model on every target move
  (t -> t + 1 with t % target_period == 0): random walk: to each in-bounds neighbour alike;
  herd (shared, unknown direction): the same, plus the deviation's stay (10 % / 3) and the
  stay of a target pushed against the border. Cells in view are then set from the view, and
  the shown targets' attribution is capped by the population sizes (no more unfound ones
  shown than remain), and the mass outside the view is rescaled so the populations keep their known sizes
  (R - n_found unfound, n_found found): a probability-hypothesis-density filter with known
  cardinality. An episode still running (obs.active) has at least one target left, which
  caps n_found at R - 1 while it runs. The support is exact (a target can only be where its density is > 0: the
  motion kernel covers every move the world makes); the spread within it is approximate
  (targets do not share cells; the herd's direction is not estimated).
"""

from __future__ import annotations

import numpy as np

from sim.gridworld import GridConfig

from .soft import SoftView, fill, look

#: the planes() channels, in order
PLANE_NAMES: tuple[str, ...] = (
    "visited",  # P(cell visited)
    "seen",  # P(cell shown by the view at least once)
    "target",  # expected not-yet-found targets in the cell now
    "found",  # expected already-found targets in the cell now
    "agent",  # the agent's cell distribution (one-hot when the position is exact)
    "prior",  # placement prior times R: the expected targets per cell before any observation
    "staleness",  # min(age / 30, 1): how long ago the view last showed the cell
    "on_map",  # 1 everywhere on the field (tells a zero-padded convolution where the border is)
)
BELIEF_CHANNELS = len(PLANE_NAMES)
_STALE_SCALE = 30.0
#: probability mass kept in place for a random walker whose free neighbours are all taken
_BLOCKED = 1e-3
#: share of a population's size kept outside the view when the view seems to hold all of it
#: (a found target counted as unfound): the mass never vanishes, so the support stays exact
_LEAK = 1e-3
#: bound on |log g| of the pair correlation, so that no finite sample rules a cell out entirely
_LOG_PAIR_CAP = 6.0
#: a static search under a GPS posterior whose unsighted targets have less than this share of
#: the placement prior left unseen reopens the cells not visited (_reopen_if_exhausted)
SOFT_DRY = 0.02
#: the floor of where a target sighted beyond the view can be (BeliefState._fold_far): a cell
#: the view showed empty may still hold it, if the camera was off that cell
FAR_EPS = 0.005
#: the floor of a view slot's likelihood (policy.belief.state.BeliefState._view_likelihood)
VIEW_EPS = 0.02
#: under soft evidence (altitude levels), a cell believed occupied with more than this is
#: "sighted": a target to recover close up, not a place to look
SIGHTED = 0.5
#: the view's 9 slots (dy, dx), row-major like views[:, :, dy + 1, dx + 1]
_SLOTS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
_SLOT_DY = np.array([dy for dy, _ in _SLOTS])
_SLOT_DX = np.array([dx for _, dx in _SLOTS])
_SLOT_CENTRE = (_SLOT_DY == 0) & (_SLOT_DX == 0)


def uniform_prior(cfg: GridConfig) -> np.ndarray:
    return np.full((cfg.height, cfg.width), 1.0 / (cfg.width * cfg.height))


def _shift(a: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """out[..., y, x] = a[..., y - dy, x - dx], zero where that falls off the grid."""
    out = np.zeros_like(a)
    h, w = a.shape[-2:]
    ys, yd = (slice(0, h - dy), slice(dy, h)) if dy >= 0 else (slice(-dy, h), slice(0, h + dy))
    xs, xd = (slice(0, w - dx), slice(dx, w)) if dx >= 0 else (slice(-dx, w), slice(0, w + dx))
    out[..., yd, xd] = a[..., ys, xs]
    return out


def weighted_rows(weights: np.ndarray, table: np.ndarray) -> np.ndarray:
    """weights (n, K) @ table (K, M), each row summed term by term in the order of K, its zero
    weights skipped (adding 0 * x changes no sum), in the weights' and table's dtype.

    Why not `weights @ table`: a BLAS product's rounding depends on its thread count and on the
    batch (OpenBLAS with 1 and 2 threads gives other float32 sums at (10, 400) x (400, 400), so
    the planner's decisions depended on the machine); and on a loaded 2-core machine its threads
    spin: (10, 400) x (400, 400) took 23 ms instead of 0.3 ms, most of a 20 x 20 DAgger
    rollout. Here a row depends only on its own weights (the same alone as in any batch), and
    the belief's weights are sparse (the few sighted and found cells of a static search): step j
    adds every row's j-th nonzero term, as many steps as the densest row has nonzeros (dense
    weights: one pass per column instead, the same sums)."""
    n = weights.shape[0]
    out = np.zeros((n, table.shape[1]), np.result_type(weights, table))
    rows, cols = np.nonzero(weights)
    if len(rows) == 0:
        return out
    if len(rows) * 4 > weights.size:  # dense (a diffused density): one pass per column, no gather
        for k in np.flatnonzero(weights.any(axis=0)):
            out += weights[:, k, None] * table[k]
        return out
    counts = np.bincount(rows, minlength=n)
    first = np.cumsum(counts) - counts
    rank = np.arange(len(rows)) - first[rows]  # position of each nonzero within its row
    width = int(counts.max())
    idx = np.zeros((n, width), np.int64)
    wgt = np.zeros((n, width), weights.dtype)
    idx[rows, rank] = cols
    wgt[rows, rank] = weights[rows, cols]
    by_count = np.argsort(-counts, kind="stable")  # rows with more nonzeros first
    ordered = counts[by_count]
    for j in range(width):
        sel = by_count[: int(np.searchsorted(-ordered, -j, side="left"))]  # rows with > j nonzeros
        out[sel] += wgt[sel, j, None] * table[idx[sel, j]]
    return out

def offmap_table(h: int, w: int) -> np.ndarray:
    """(h, w, 3, 3) bool: whether view slot (dy, dx) is off the map for an agent at (x, y)."""
    ys = np.arange(h)[:, None, None, None] + np.arange(-1, 2)[None, None, :, None]
    xs = np.arange(w)[None, :, None, None] + np.arange(-1, 2)[None, None, None, :]
    return (ys < 0) | (ys >= h) | (xs < 0) | (xs >= w)


def motion_kernel(cfg: GridConfig, a: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """One target move applied to densities a (..., h, w) (see the module docstring). mask:
    (..., h, w) bool searchable cells (a masked cell is off the map for a target too), or None."""
    if not cfg.moving:
        return a
    if mask is not None:
        return _masked_motion_kernel(cfg, a, mask)
    h, w = a.shape[-2:]
    ones = np.ones((h, w))
    # number of in-bounds neighbours per cell
    nb = sum(_shift(ones, dy, dx) for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1)))
    if cfg.motion == "random_walk":
        # all 8 tries land off the map (a corner: (2/4)^8), or every free neighbour is taken
        # (rare; kept as a small floor so that the support stays exact): the target stays
        stay = ((4 - nb) / 4.0) ** 8 + _BLOCKED
        share = a * (1.0 - stay) / nb
        return a * stay + sum(_shift(share, dy, dx) for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1)))
    stay = cfg.herd_deviation / 3.0
    move = (1.0 - stay) / 4.0
    out = a * (stay + move * (4 - nb))  # deviation's stay + pushes against the border
    return out + sum(_shift(a * move, dy, dx) for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1)))


def _masked_motion_kernel(cfg: GridConfig, a: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """motion_kernel on masked fields: the neighbours counted are the searchable ones, and mass
    only moves into them (the world's walker redraws a masked step like an off-map one, a herd
    member stays), so the mass is kept and never enters a masked cell."""
    on = mask.astype(a.dtype)
    moves = ((1, 0), (-1, 0), (0, 1), (0, -1))
    # searchable neighbours per cell: a cell's neighbour c' counts when c' is on the map and searchable
    nb = sum(_shift(on, -dy, -dx) for dy, dx in moves)
    if cfg.motion == "random_walk":
        stay = ((4 - nb) / 4.0) ** 8 + _BLOCKED
        share = a * (1.0 - stay) / np.maximum(nb, 1)
        share = np.where(nb > 0, share, 0.0)
        stay = np.where(nb > 0, stay, 1.0)
        return (a * stay + sum(_shift(share, dy, dx) for dy, dx in moves)) * on
    stay = cfg.herd_deviation / 3.0
    move = (1.0 - stay) / 4.0
    out = a * (stay + move * (4 - nb))
    return (out + sum(_shift(a * move, dy, dx) for dy, dx in moves)) * on


def offmap_table_masked(mask: np.ndarray) -> np.ndarray:
    """(n, h, w, 3, 3) bool: offmap_table per episode, a masked cell counting as off the map
    (the world's view shows it so)."""
    n, h, w = mask.shape
    ys = np.arange(h)[:, None, None, None] + np.arange(-1, 2)[None, None, :, None]
    xs = np.arange(w)[None, :, None, None] + np.arange(-1, 2)[None, None, None, :]
    off = (ys < 0) | (ys >= h) | (xs < 0) | (xs >= w)
    on = mask[:, np.clip(ys, 0, h - 1), np.clip(xs, 0, w - 1)]
    return off[None] | ~on


class BeliefState:
    """Batched belief over n episodes of one GridConfig, computed from observations only.

    Call update(obs) once per decision, including the first (obs.t == 0). See the module
    docstring for the model; PLANE_NAMES for the network input."""

    def __init__(self, cfg: GridConfig, n: int, prior: np.ndarray | None = None,
                 pair: np.ndarray | None = None, view_evidence: bool = True,
                 mask: np.ndarray | None = None) -> None:
        """prior: (h, w) placement density or None (uniform). pair: (2h - 1, 2w - 1) pair
        correlation g(dy, dx) of the placement (policy.belief.prior.estimate_pair) or None
        (targets placed independently): static targets only, see _pool. view_evidence: under
        a GPS posterior, also condition the position on the view's targets (_view_likelihood);
        False conditions on the off-map pattern only, as before Dec 2026. mask: (h, w) or
        (n, h, w) bool searchable cells (sim.gridworld.masks), None = the whole grid: masked
        cells have zero prior (no target is there, none moves there)."""
        if n < 1:
            raise ValueError(f"n must be >= 1 (got {n})")
        h, w = cfg.height, cfg.width
        if prior is None:
            prior = uniform_prior(cfg)
        prior = np.asarray(prior, dtype=np.float64)
        if prior.shape != (h, w):
            raise ValueError(f"prior must have shape {(h, w)} for this grid (got {prior.shape})")
        if not np.all(np.isfinite(prior)) or (prior < 0).any() or prior.sum() <= 0:
            raise ValueError("prior must be finite, non-negative and not all zero")
        self.cfg, self.n = cfg, n
        self.prior = prior / prior.sum()
        #: (n, h, w) bool searchable cells, or None (the whole grid)
        self.mask: np.ndarray | None = None
        #: (1, h, w) prior, or (n, h, w) the prior on each episode's searchable cells
        self._prior_n = self.prior[None]
        if mask is not None:
            from sim.gridworld.masks import episode_masks

            self.mask = episode_masks(mask, n, h, w)
            mp = self.prior[None] * self.mask
            tot = mp.sum(axis=(1, 2), keepdims=True)
            # a prior with no mass on a field's searchable cells: uniform over them
            mp = np.where(tot > 0, mp / np.maximum(tot, 1e-300), self.mask / self.mask.sum(axis=(1, 2), keepdims=True))
            self._prior_n = mp
        self.rows = np.arange(n)
        r = float(cfg.n_targets)
        f32 = np.float32
        self.visited = np.zeros((n, h, w), f32)
        self.seen = np.zeros((n, h, w), f32)
        self.found = np.zeros((n, h, w), f32)
        self.age = np.zeros((n, h, w), f32)
        self.position = np.zeros((n, h, w), f32)
        self.n_found = np.zeros(n, np.float64)
        self.t = np.full(n, -1, np.int64)
        #: static: sighted-not-found mass; moving: the whole unfound density
        self._sighted = np.zeros((n, h, w), f32)
        if cfg.moving:
            self._sighted[:] = (r * self._prior_n).astype(f32)
        self._offmap = offmap_table(h, w) if self.mask is None else offmap_table_masked(self.mask)
        self._pair = None
        if pair is not None and not cfg.moving:
            pair = np.asarray(pair, dtype=np.float64)
            if pair.shape != (2 * h - 1, 2 * w - 1) or not np.all(pair > 0):
                raise ValueError(f"pair must be positive with shape {(2 * h - 1, 2 * w - 1)} (got {pair.shape})")
            # M[c', c] = log g(c - c'): the log-factor a target at c' puts on a target at c
            cy, cx = np.divmod(np.arange(h * w), w)
            dy = cy[None, :] - cy[:, None] + h - 1
            dx = cx[None, :] - cx[:, None] + w - 1
            self._pair = np.clip(np.log(pair[dy, dx]), -_LOG_PAIR_CAP, _LOG_PAIR_CAP).astype(np.float32)
        #: every position so far was exact, so visited and seen are 0/1 (update's fast path)
        self._crisp = True
        #: prior * (1 - seen) while _crisp (static targets' pool weight)
        self._unseen_prior = np.repeat(self.prior[None], n, axis=0) if self.mask is None else \
            self._prior_n.astype(np.float64)
        self._reopened = False
        #: (n,) some position so far was uncertain (a posterior with no cell at >= 0.999)
        self._uncertain = np.zeros(n, bool)
        #: condition a GPS position posterior on the view's targets too (_view_likelihood)
        self.view_evidence = view_evidence
        #: the view is a sample of detections (altitude levels, policy.belief.soft): the whole
        #: unfound density is tracked per cell, as for moving targets, on soft evidence
        self.soft: SoftView | None = None
        if not cfg.perfect_detection:
            self.soft = SoftView(cfg)
            self._pair = None
            self._sighted[:] = (r * self.prior).astype(f32)
            #: (n,) level flown at the last update
            self.level = np.ones(n, np.int64)
        self.target = self._target()

    # ----------------------------------------------------------------- derived quantities
    def _pool(self, sighted_sum: np.ndarray | None = None) -> np.ndarray:
        """Static: the never-sighted targets, R - n_found - sighted, over the unseen cells.
        sighted_sum: the (n,) float64 sums of _sighted when the caller has them already."""
        if sighted_sum is None:
            sighted_sum = self._sighted.sum(axis=(1, 2), dtype=np.float64)
        left = self.cfg.n_targets - self.n_found - sighted_sum
        weight = self._unseen_weight()
        if self._pair is not None:
            # pairwise placement structure: each known target (sighted or found) multiplies the
            # density of the others by the pair correlation at their offset (a lattice's spacing)
            known = (self._sighted + self.found).reshape(self.n, -1)
            logf = weighted_rows(known, self._pair).reshape(weight.shape)
            weight = weight * np.exp(logf - logf.max(axis=(1, 2), keepdims=True))
        tot = weight.sum(axis=(1, 2))
        scale = np.where(tot > 1e-12, np.maximum(left, 0.0) / np.maximum(tot, 1e-12), 0.0)
        return (weight * scale[:, None, None]).astype(np.float32)

    def _unseen_weight(self) -> np.ndarray:
        """(n, h, w) prior * (1 - seen): where never-sighted static targets can be. Kept up to
        date cell by cell while seen is 0/1 (the same numbers)."""
        return self._unseen_prior if self._crisp else self._prior_n * (1.0 - self.seen)

    def _target(self, sighted_sum: np.ndarray | None = None) -> np.ndarray:
        if self.cfg.moving or self.soft is not None:
            return self._sighted.copy()
        return self._sighted + self._pool(sighted_sum)

    @property
    def sighted(self) -> np.ndarray:
        """(n, h, w) static: targets the view has shown that are believed not found yet
        (moving: the whole unfound density; there is no separate never-sighted pool). Under soft
        evidence (static): the cells believed more likely occupied than not (SIGHTED)."""
        if self.soft is not None and not self.cfg.moving:
            return np.where(self._sighted > SIGHTED, self._sighted, np.float32(0.0))
        return self._sighted

    @property
    def remaining(self) -> np.ndarray:
        """(n,) believed targets not found yet."""
        return self.cfg.n_targets - self.n_found

    @property
    def unsighted(self) -> np.ndarray:
        """(n,) static: believed targets never shown by the view (0 means all are sighted);
        under soft evidence, those not in a cell believed occupied (sighted)."""
        if self.soft is not None and not self.cfg.moving:
            return np.maximum(self.remaining - self.sighted.sum(axis=(1, 2), dtype=np.float64), 0.0)
        return np.maximum(self.remaining - self._sighted.sum(axis=(1, 2), dtype=np.float64), 0.0)

    # ----------------------------------------------------------------------- the update
    def _position(self, obs) -> np.ndarray:
        h, w = self.cfg.height, self.cfg.width
        if obs.position_prob is None:
            p = np.zeros((self.n, h, w), np.float32)
            pos = np.asarray(obs.positions)
            p[self.rows, pos[:, 1], pos[:, 0]] = 1.0
            return p
        p = np.asarray(obs.position_prob, dtype=np.float32)
        if p.shape != (self.n, h, w):
            raise ValueError(f"position_prob must be {(self.n, h, w)} (got {p.shape})")
        # keep the cells whose off-map pattern matches the view's off-map channel
        off = np.asarray(obs.views)[:, 1].astype(bool)  # (n, 3, 3)
        table = self._offmap[None] if self._offmap.ndim == 4 else self._offmap  # masked: per episode
        agree = np.all(table == off[:, None, None], axis=(3, 4))  # (n, h, w)
        q = p * agree
        if self.view_evidence:
            q = q * self._view_likelihood(np.asarray(obs.views)[:, 0])
        tot = q.sum(axis=(1, 2), keepdims=True)
        q = np.where(tot > 1e-9, q / np.maximum(tot, 1e-9), p / np.maximum(p.sum(axis=(1, 2), keepdims=True), 1e-9))
        return q.astype(np.float32)

    def _view_likelihood(self, tgt_slots: np.ndarray) -> np.ndarray:
        """(n, h, w) how well the view's target channel fits the agent standing on each cell,
        scaled to a maximum of 1: each slot showing a target counts P(a target is there) by the
        belief, each empty one 1 - that, both floored at VIEW_EPS (the view can be wrong).

        Why: the view is taken from where the agent truly is. Spread over a GPS posterior alone,
        a found target shown one cell east, seen from the cell west of the believed one, puts a
        phantom unfound target on the believed cell (nobody expected one there, so it counts as
        new). The planner came back for it, and left it again, for a dozen moves (flight seed 5:
        56 moves against 34 in the grid world). A position under which the view shows known
        targets where they are is the likely one."""
        u = self.target if not self.cfg.moving else self._sighted
        occ = np.clip(u + self.found, VIEW_EPS, 1.0 - VIEW_EPS)
        logl = np.zeros_like(occ)
        for dy, dx in _SLOTS:
            o = _shift(occ, -dy, -dx)  # o[y, x] = occ[y + dy, x + dx]: the cell in slot (dy, dx)
            shown = tgt_slots[:, dy + 1, dx + 1, None, None] > 0
            # off the grid _shift gives 0: an off-map slot shows nothing, a factor of 1
            logl += np.where(shown, np.log(np.maximum(o, VIEW_EPS)), np.log1p(-o))
        return np.exp(logl - logl.max(axis=(1, 2), keepdims=True))

    def update(self, obs) -> None:
        """Fold one decision's observation (views, positions, t, active, position_prob) in."""
        cfg = self.cfg
        if self.soft is not None:
            self._update_soft(obs)
            return
        if self.n == 1 and obs.position_prob is None and self._crisp and not cfg.moving:
            self._update_one(obs)
            self._fold_far(obs)
            return
        t = np.asarray(obs.t, dtype=np.int64)
        views = np.asarray(obs.views)
        if views.shape[1:] != (3, 3, 3) or len(views) != self.n:
            raise ValueError(f"views must be ({self.n}, 3, 3, 3) grid views (got {views.shape})")
        self._advance(t)
        p = self._position(obs)
        self.position = p
        if obs.position_prob is not None:
            self._uncertain |= p.reshape(self.n, -1).max(axis=1) < 0.999

        tgt_slots = views[:, 0].astype(np.float32)  # (n, 3, 3)
        # the unfound density before this observation: self.target is what _target() returned at
        # the end of the last update (nothing it reads has changed since)
        u = self.target if not cfg.moving else self._sighted
        exact = obs.position_prob is None
        if exact:
            cells, det_u_c, det_f_c, newly = self._view_exact(obs.positions, tgt_slots, u)
        else:
            self._crisp = False
            # the flight's companion (obs.found_now) shows a target in the centre slot where it
            # stands on the cell the agent was told (found now, or found there before): its
            # found mass goes there, not spread over the position posterior (spread, a cow found
            # with the posterior leaning a row south stood there as a phantom found cow, and the
            # view's evidence then kept the agent believed a row off: flight seed 25)
            told = np.asarray(obs.positions, dtype=np.int64) if getattr(obs, "found_now", None) is not None else None
            keep, det_u, det_f, newly = self._view_spread(p, tgt_slots, u, told)
        events = self._find_events(obs)
        if events is not None:
            newly = events
        # an episode still running has at least one target left (the mission ends with the last)
        cap = np.where(np.asarray(obs.active, dtype=bool), cfg.n_targets - 1, cfg.n_targets)
        self.n_found = np.minimum(self.n_found + newly, cap)
        sighted_sum = None
        if exact and not cfg.moving:
            # the arrays below, computed on the <= 9 cells in view only: out of view keep is 1
            # (x * 1 + 0 == x), in view it is 0 (0 + det == det), so this is the whole-array
            # update bit for bit; _cap changes nothing unless a sum exceeds its bound
            sighted = self._sighted.copy()
            sighted[cells] = det_u_c
            found = self.found.copy()
            found[cells] = det_f_c
            sighted_sum = sighted.sum(axis=(1, 2), dtype=np.float64)
            if (sighted_sum > self.remaining + 1e-6).any():
                sighted, sighted_sum = self._cap(sighted, self.remaining), None
            if (found.sum(axis=(1, 2), dtype=np.float64) > self.n_found + 1e-6).any():
                found = self._cap(found, self.n_found)
            self._sighted, self.found = sighted, found
        else:
            if exact:
                keep, det_u, det_f = self._view_arrays(cells, det_u_c, det_f_c)
            if cfg.moving:
                # the shown targets cannot hold more unfound (found) ones than there are: move
                # the excess of either attribution to the other
                for src, dst, total in ((det_u, det_f, self.remaining), (det_f, det_u, self.n_found)):
                    have = src.sum(axis=(1, 2), dtype=np.float64)
                    over = np.where(have > total + 1e-6, 1.0 - total / np.maximum(have, 1e-9), 0.0)
                    moved = src * over[:, None, None].astype(np.float32)
                    src -= moved
                    dst += moved
                self._sighted = self._rescale(self._sighted * keep, det_u, self.remaining)
                self.found = self._rescale(self.found * keep, det_f, self.n_found)
            else:
                # under GPS noise one target shown from several possible positions spreads over
                # several cells; the sizes stay capped by what is known
                self._sighted = self._cap(self._sighted * keep + det_u, self.remaining)
                self.found = self._cap(self.found * keep + det_f, self.n_found)
        if exact and self._crisp:
            # visited and seen are 0/1 while every position so far was exact: then
            # 1 - (1 - a) * 1 == a and 1 - (1 - a) * 0 == 1, so only the cells in view change
            pos = np.asarray(obs.positions)
            self.visited = self.visited.copy()
            self.visited[self.rows, pos[:, 1], pos[:, 0]] = 1.0
            # (cells: index arrays, or one episode's block of slices)
            self.seen = self.seen.copy()
            self.seen[cells] = 1.0
            self._unseen_prior[cells] = 0.0
            self.age[cells] = 0.0
        else:
            if exact and not cfg.moving:  # the static branch above did not need keep
                keep = np.ones_like(p)
                keep[cells] = 0.0
            self.visited = 1.0 - (1.0 - self.visited) * (1.0 - p)
            self.seen = 1.0 - (1.0 - self.seen) * keep
            self.age *= keep
        self.t = t.copy()
        self._reopen_if_exhausted()
        self.target = self._target(sighted_sum if not self._reopened else None)
        self._fold_far(obs)

    def _advance(self, t: np.ndarray) -> None:
        """Time passes: ages grow, and moving targets' densities diffuse once per target move
        (transitions s -> s + 1 with s % period == 0, s in [prev, t))."""
        cfg = self.cfg
        prev = np.where(self.t < 0, t, self.t)
        dt = np.maximum(t - prev, 0)
        if cfg.moving:
            per = cfg.target_period
            moves = (t + per - 1) // per - (prev + per - 1) // per
            for k in range(int(moves.max(initial=0))):
                rows = moves > k
                mk = None if self.mask is None else self.mask[rows]  # the field's cells only
                self._sighted[rows] = motion_kernel(cfg, self._sighted[rows], mk)
                self.found[rows] = motion_kernel(cfg, self.found[rows], mk)
        self.age += dt[:, None, None].astype(np.float32)

    def _update_soft(self, obs) -> None:
        """update() where the view is a sample of detections (policy.belief.soft): exact
        positions, the level flown (obs.level; None: 1), finds from obs.found_now (the world
        counts them; without it, the view's own cell at level 1 says it)."""
        cfg, sv = self.cfg, self.soft
        if obs.position_prob is not None:
            raise ValueError("the soft-evidence belief (altitude levels) takes exact positions only")
        views = np.asarray(obs.views)
        k = sv.width
        if views.ndim != 4 or views.shape[0] != self.n or views.shape[2:] != (k, k):
            raise ValueError(f"views must be ({self.n}, C, {k}, {k}) windows for levels = {cfg.levels} "
                             f"(got {views.shape})")
        t = np.asarray(obs.t, dtype=np.int64)
        self._advance(t)
        level = getattr(obs, "level", None)
        level = np.ones(self.n, np.int64) if level is None else np.asarray(level, np.int64).reshape(self.n)
        if (level < 1).any() or (level > cfg.levels).any():
            raise ValueError(f"level must be in 1..{cfg.levels} (got {level})")
        self.level = level.copy()
        pos = np.asarray(obs.positions, dtype=np.int64)
        p = np.zeros_like(self.position)
        p[self.rows, pos[:, 1], pos[:, 0]] = 1.0
        self.position = p
        cells, slot, pd, fa = sv.cells(pos, level)
        detected = views[:, 0].reshape(self.n, -1)[cells[0], slot] > 0
        u, f = look(self._sighted[cells], self.found[cells], detected, pd, fa)
        sighted, found = self._sighted.astype(np.float64), self.found.astype(np.float64)
        sighted[cells], found[cells] = u, f
        low = level == 1
        here = (self.rows[low], pos[low, 1], pos[low, 0])
        now = getattr(obs, "found_now", None)
        if now is None:  # the view's own cell at level 1: what it shows there is found now
            now = np.zeros(self.n)
            ctr = views[:, 0, k // 2, k // 2] > 0
            now[low & ctr] = np.minimum(self._sighted[self.rows, pos[:, 1], pos[:, 0]], 1.0)[low & ctr]
        now = np.asarray(now, np.float64).reshape(self.n)
        sighted[here] = 0.0  # a target there would have been recovered on arrival
        got = low & (now > 0)
        found[self.rows[got], pos[got, 1], pos[got, 0]] = 1.0
        cap = np.where(np.asarray(obs.active, dtype=bool), cfg.n_targets - 1, cfg.n_targets)
        self.n_found = np.minimum(self.n_found + now, cap)
        if cfg.moving:
            found = fill(found, self.n_found, np.ones_like(found))
        sighted = fill(sighted, self.remaining, np.maximum(1.0 - found, 0.0), leak=sv.leak)
        self._sighted, self.found = sighted.astype(np.float32), found.astype(np.float32)
        self.visited[here] = 1.0
        self.seen[cells] = 1.0
        self.age[cells] = 0.0
        self.t = t.copy()
        self.target = self._target()

    def _fold_far(self, obs) -> None:
        """Static targets sighted beyond the view (obs.far_targets: per sighting, its likelihood
        over cells): each is placed by Bayes over where targets can be (the unfound and found
        densities), and its unfound share raises the sighted mass there, never lowers it (the
        same target sighted again from the next cell adds nothing). Why: a real camera's frame
        shows the near end of a target one or two cells out, and which of the two is often
        not clear (the camera a metre off its cell, the GPS bias unobserved for minutes);
        dropped, the target two cells away was passed by, and the one a cell away, whose cell
        the view had marked seen, was left for a second sweep of the field (flight seeds 25,
        103: 43 and 102 moves against 24 and 36 in the grid world)."""
        far = getattr(obs, "far_targets", None)
        if far is None or self.cfg.moving:
            return
        far = np.asarray(far, dtype=np.float32)
        shape = (self.n, self.cfg.height, self.cfg.width)
        if far.ndim != 4 or far.shape[0] != self.n or far.shape[2:] != shape[1:]:
            raise ValueError(f"far_targets must be (n, k, h, w) = ({self.n}, k, {shape[1]}, {shape[2]}) "
                             f"(got {far.shape})")
        if not np.all(np.isfinite(far)) or (far < 0).any():
            raise ValueError("far_targets must be finite and non-negative")
        u, f = self.target, self.found
        ratio = np.where(u + f > 1e-9, u / np.maximum(u + f, 1e-9), 1.0)
        # where targets can be, floored (the view can be wrong: a cell marked seen from a camera
        # a metre off may hold the target)
        where = np.maximum(u + f, FAR_EPS)
        sighted = self._sighted
        for j in range(far.shape[1]):
            post = far[:, j] * where
            tot = post.sum(axis=(1, 2), keepdims=True)
            post = np.where(tot > 1e-9, post / np.maximum(tot, 1e-9), 0.0)
            sighted = np.maximum(sighted, (post * ratio).astype(np.float32))
        self._sighted = self._cap(sighted, self.remaining)
        self.target = self._target()

    def _reopen_if_exhausted(self) -> None:
        """Static targets believed left unsighted with no unseen cell to hold them: a view
        missed one (a real camera off its cell by more than half a cell sees a shifted window,
        and a cell marked seen may not have been). Every cell not visited is reopened to the
        prior, so the search sweeps the field again instead of wandering with nothing to
        look for. With exact positions and a perfect view (the grid world) this never happens:
        every cell seen means every target sighted or found."""
        self._reopened = False
        if self.cfg.moving:
            return
        weight = self._unseen_weight()
        # once a position was uncertain (a GPS posterior, not one-hot) seen is never quite 1:
        # a whole target believed in under SOFT_DRY of the prior's mass is the same contradiction
        dry = (self.unsighted > 0.5) & (weight.sum(axis=(1, 2)) < np.where(self._uncertain, SOFT_DRY, 1e-9))
        if not dry.any():
            return
        self._reopened = True
        self.seen[dry] = np.minimum(self.seen[dry], self.visited[dry])
        self._unseen_prior[dry] = (self.prior[None] if self.mask is None else self._prior_n[dry]) * (1.0 - self.visited[dry])

    def _update_one(self, obs) -> None:
        """update() for one episode with an exact position and static targets while visited and
        seen are 0/1 (the flight's case): the same numbers bit for bit (tested against the
        general path), with the episode's scalars as Python floats (IEEE doubles, like numpy's
        float64) and array work only on the cells in view and the pool: at batch 1 numpy's
        per-call cost, not the arithmetic, is what a decision pays."""
        views = np.asarray(obs.views)
        if views.shape != (1, 3, 3, 3):
            raise ValueError(f"views must be (1, 3, 3, 3) grid views (got {views.shape})")
        t = int(np.asarray(obs.t).reshape(-1)[0])
        prev = int(self.t[0])
        dt = max(t - prev, 0) if prev >= 0 else 0
        if dt:
            self.age += np.float32(dt)
        x, y = (int(v) for v in np.asarray(obs.positions).reshape(2))
        p = np.zeros_like(self.position)
        p[0, y, x] = 1.0
        self.position = p
        cells, det_u_c, det_f_c, newly = self._view_exact_one(obs.positions, views[:, 0].astype(np.float32),
                                                              self.target)
        events = self._find_events(obs)
        new = float((events if events is not None else newly)[0])
        r = self.cfg.n_targets
        cap = r - 1 if bool(np.asarray(obs.active).reshape(-1)[0]) else r
        n_found = min(float(self.n_found[0]) + new, cap)
        self.n_found = np.array([n_found], np.float64)
        sighted = self._sighted.copy()
        sighted[cells] = det_u_c
        found = self.found.copy()
        found[cells] = det_f_c
        sighted_sum = sighted.sum(axis=(1, 2), dtype=np.float64)
        if sighted_sum[0] > (r - n_found) + 1e-6:
            sighted, sighted_sum = self._cap(sighted, self.remaining), None
        if found.sum(axis=(1, 2), dtype=np.float64)[0] > n_found + 1e-6:
            found = self._cap(found, self.n_found)
        self._sighted, self.found = sighted, found
        self.visited = self.visited.copy()
        self.visited[0, y, x] = 1.0
        self.seen = self.seen.copy()
        self.seen[cells] = 1.0
        self._unseen_prior[cells] = 0.0
        self.age[cells] = 0.0
        self.t = np.array([t], np.int64)
        self._reopen_if_exhausted()
        if self._pair is not None or sighted_sum is None or self._reopened:
            self.target = self._target(sighted_sum)
            return
        # _pool with Python scalars: left, the unseen prior's total and the scale
        left = r - n_found - float(sighted_sum[0])
        weight = self._unseen_prior
        tot = float(weight.sum(axis=(1, 2))[0])
        scale = max(left, 0.0) / max(tot, 1e-12) if tot > 1e-12 else 0.0
        self.target = sighted + (weight * scale).astype(np.float32)

    def _view_arrays(self, cells: tuple[np.ndarray, ...], det_u_c: np.ndarray,
                     det_f_c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """_view_exact's cells as _view_spread's whole arrays (keep, det_u, det_f)."""
        shape = (self.n, self.cfg.height, self.cfg.width)
        keep = np.ones(shape, np.float32)
        keep[cells] = 0.0
        det_u = np.zeros(shape, np.float32)
        det_u[cells] = det_u_c
        det_f = np.zeros(shape, np.float32)
        det_f[cells] = det_f_c
        return keep, det_u, det_f

    def _view_spread(self, p: np.ndarray, tgt_slots: np.ndarray, u: np.ndarray,
                     told: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What the view showed, for a position distribution p: (keep = 1 - P(in view), unfound
        targets shown outside the agent's cell, found targets shown, expected new finds). told:
        (n, 2) cells (x, y) the centre slot's targets stand on, where the observer says so (the
        flight's); else the centre slot is spread over p like the others."""
        f = self.found
        tot = u + f
        ratio_u = np.where(tot > 1e-9, u / np.maximum(tot, 1e-9), 1.0)
        inview = np.zeros_like(p)
        det_u = np.zeros_like(p)  # unfound targets shown outside the agent's cell
        det_f = np.zeros_like(p)  # found targets shown
        for dy, dx in _SLOTS:
            ps = _shift(p, dy, dx)  # P(cell shown in slot (dy, dx))
            inview += ps
            shown = ps * tgt_slots[:, dy + 1, dx + 1, None, None]
            if dy == 0 and dx == 0:
                newly = (shown * ratio_u).sum(axis=(1, 2), dtype=np.float64)
                if told is not None:
                    shown = np.zeros_like(p)
                    shown[self.rows, told[:, 1], told[:, 0]] = tgt_slots[:, 1, 1]
                det_f += shown
            else:
                det_u += shown * ratio_u
                det_f += shown * (1.0 - ratio_u)
        return 1.0 - np.minimum(inview, 1.0), det_u, det_f, newly

    def _view_exact(self, positions: np.ndarray, tgt_slots: np.ndarray,
                    u: np.ndarray) -> tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray, np.ndarray]:
        """_view_spread for known positions (p one-hot), the same numbers bit for bit, on the
        cells in view only: each in-map slot shows exactly one cell, so the sums over slots
        reduce to one term per cell (adding zeros is exact). Returns (cells: index arrays
        (episode, y, x) of the cells in view, det_u and det_f there, expected new finds)."""
        n, (h, w) = self.n, (self.cfg.height, self.cfg.width)
        if n == 1:
            return self._view_exact_one(positions, tgt_slots, u)
        pos = np.asarray(positions, dtype=np.int64)
        ys = pos[:, 1, None] + _SLOT_DY  # (n, 9)
        xs = pos[:, 0, None] + _SLOT_DX
        ok = (ys >= 0) & (ys < h) & (xs >= 0) & (xs < w)
        cells = (np.broadcast_to(self.rows[:, None], ok.shape)[ok], ys[ok], xs[ok])
        ctr = np.broadcast_to(_SLOT_CENTRE, ok.shape)[ok]
        uu = u[cells]
        tot = uu + self.found[cells]
        ratio = np.where(tot > 1e-9, uu / np.maximum(tot, 1e-9), 1.0)
        tg = tgt_slots.reshape(n, 9)[ok]
        shown_u = tg * ratio
        # the agent's own cell: every target shown there is found (det_f), the unfound share of
        # it is the expected new find; the other cells split by the unfound share
        det_u = np.where(ctr, np.float32(0.0), shown_u)
        det_f = np.where(ctr, tg, tg * (1.0 - ratio))
        newly = np.zeros(n, np.float64)
        newly[cells[0][ctr]] = shown_u[ctr]
        return cells, det_u, det_f, newly

    def _view_exact_one(self, positions: np.ndarray, tgt_slots: np.ndarray,
                        u: np.ndarray) -> tuple[tuple, np.ndarray, np.ndarray, np.ndarray]:
        """_view_exact for one episode (the flight): the cells in view are a block, indexed by
        slices, and the same element-wise arithmetic runs on that block."""
        h, w = self.cfg.height, self.cfg.width
        x, y = (int(v) for v in np.asarray(positions).reshape(2))
        y0, y1, x0, x1 = max(y - 1, 0), min(y + 2, h), max(x - 1, 0), min(x + 2, w)
        cells = (0, slice(y0, y1), slice(x0, x1))
        uu = u[cells]
        tot = uu + self.found[cells]
        ratio = np.where(tot > 1e-9, uu / np.maximum(tot, 1e-9), 1.0)
        tg = tgt_slots[0, y0 - y + 1: y1 - y + 1, x0 - x + 1: x1 - x + 1]
        det_u = tg * ratio
        centre = (y - y0, x - x0)
        newly = np.array([det_u[centre]], np.float64)
        det_u[centre] = 0.0
        det_f = tg * (1.0 - ratio)
        det_f[centre] = tg[centre]
        return cells, det_u, det_f, newly

    def _find_events(self, obs) -> np.ndarray | None:
        """(n,) targets found by the last move, where the map M says it: the spatiotemporal
        map's recoveries channel is written (trail_value) at the agent's cell in the step of a
        find. None where the map does not tell (spatial and memory maps) or the position is
        uncertain; then the belief's own expectation is used. obs.found_now, where given, says
        it outright (the flight's companion knows each find: under an uncertain position the
        expectation had counted a cow seen from the next cell as a part-find, 2.67 believed of
        2 found, and the planner went back and forth between the two cows for 12 moves, flight
        seed 25)."""
        now = getattr(obs, "found_now", None)
        if now is not None:
            now = np.asarray(now, dtype=np.float64).reshape(-1)
            if now.shape != (self.n,) or not np.all(np.isfinite(now)) or (now < 0).any():
                raise ValueError(f"found_now must be ({self.n},) finite counts >= 0 (got {now!r})")
            return now
        maps = np.asarray(obs.maps) if obs.maps is not None else None
        cfg = self.cfg
        if (cfg.map_variant != "spatiotemporal" or obs.position_prob is not None or maps is None
                or maps.ndim != 4 or maps.shape[1] != 2):
            return None
        pos = np.asarray(obs.positions)
        rec = maps[self.rows, 1, pos[:, 1], pos[:, 0]]
        return (rec >= cfg.trail_value - 0.5).astype(np.float64)

    @staticmethod
    def _cap(a: np.ndarray, total: np.ndarray) -> np.ndarray:
        have = a.sum(axis=(1, 2), dtype=np.float64)
        scale = np.where(have > total + 1e-6, total / np.maximum(have, 1e-9), 1.0)
        return (a * scale[:, None, None]).astype(np.float32)

    @staticmethod
    def _rescale(rest: np.ndarray, det: np.ndarray, total: np.ndarray) -> np.ndarray:
        """rest + det with rest scaled so the whole sums to total (rest unchanged if empty)."""
        have = rest.sum(axis=(1, 2), dtype=np.float64)
        want = np.maximum(total - det.sum(axis=(1, 2), dtype=np.float64), _LEAK * total)
        scale = np.where(have > 1e-9, want / np.maximum(have, 1e-9), 1.0)
        return (rest * scale[:, None, None] + det).astype(np.float32)

    # ------------------------------------------------------------------------- outputs
    def planes(self, out: np.ndarray | None = None, constants: bool = True) -> np.ndarray:
        """(n, BELIEF_CHANNELS, h, w) float32 network input; channels as PLANE_NAMES.
        out: an array of that shape to fill instead of a new one (the decision path's buffer);
        constants=False: out holds this belief's prior and on-map planes already (they never
        change), leave them."""
        n, (h, w) = self.n, (self.cfg.height, self.cfg.width)
        if out is None:
            out, constants = np.empty((n, BELIEF_CHANNELS, h, w), np.float32), True
        elif out.shape != (n, BELIEF_CHANNELS, h, w):
            raise ValueError(f"out must have shape {(n, BELIEF_CHANNELS, h, w)} (got {out.shape})")
        out[:, 0] = self.visited
        out[:, 1] = self.seen
        out[:, 2] = self.target
        out[:, 3] = self.found
        out[:, 4] = self.position
        out[:, 6] = np.where(self.seen > 0, np.minimum(self.age / _STALE_SCALE, 1.0), 1.0)
        if constants:
            out[:, 5] = (self.prior * self.cfg.n_targets)[None] if self.mask is None else \
                self._prior_n * self.cfg.n_targets
            # on_map: the field's searchable cells (a masked cell is off the field)
            out[:, 7] = 1.0 if self.mask is None else self.mask
        return out
