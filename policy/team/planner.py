"""`belief` for a team (issue 29): today's information-per-step rule on the shared belief, with
the goals allocated to agents by sequential greedy claims, and the moves separated.

Each joint step, on the team's belief (policy.belief.shared.SharedBelief: one belief, or one
copy per agent where sharing is delayed or lossy):
- every agent's value of a goal cell g is today's (policy.planner.planner):
      value_i(g) = (reveal(g) + pickup * target(g)) / (d_i(g) + travel_offset)
  times `region` where another agent stands strictly nearer g than agent i (the information
  regions: each agent's Voronoi cell of the field, by Manhattan distance, is worth more to it);
- sequential greedy allocation: the agent with the best value picks its goal first; the goal's
  neighbourhood (Chebyshev radius `claim_radius`) loses `claim` of its reveal and the goal's
  targets are taken (target = 0 there) for the agents after it; then the next agent picks, and
  so on. So no two agents head for one sighted target, nor for one unexplored patch;
- once every target is sighted (static targets), the value rule with nothing left to reveal
  is nearest-claim: each agent takes the nearest target nobody before it claimed;
- each agent's move is a shortest-path move towards its goal (the one whose next view reveals
  more), separated by policy.team.base.separate in the allocation's order: no two agents in
  one cell, no swaps (the world's rule, never triggered by this policy but where boxed in).

N = 1 is today's planner itself (BeliefPlanner, the same object and streams): the same moves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.gridworld import DELTAS, GridConfig

from ..base import Observation
from ..belief.shared import CommsModel, SharedBelief
from ..planner import BeliefPlanner, PlannerParams
from ..planner.planner import _window
from .base import TeamObservation, TeamPolicy, separate


@dataclass(frozen=True)
class TeamParams:
    """The allocation's weights (tuned on tuning seeds, never the test seeds; results/fleet_search.md)."""

    #: factor on a goal's value where another agent is strictly nearer it (1: no regions)
    region: float = 0.5
    #: share of reveal a claimed goal's neighbourhood loses for the agents after it
    claim: float = 0.8
    #: Chebyshev radius of that neighbourhood (2: the goal's view and the ring around it)
    claim_radius: int = 2

    def __post_init__(self) -> None:
        if not 0.0 <= self.region <= 1.0:
            raise ValueError(f"TeamParams.region must be in [0, 1] (got {self.region})")
        if not 0.0 <= self.claim <= 1.0:
            raise ValueError(f"TeamParams.claim must be in [0, 1] (got {self.claim})")
        if not 0 <= self.claim_radius <= 10:
            raise ValueError(f"TeamParams.claim_radius must be in 0..10 (got {self.claim_radius})")


class TeamBeliefPlanner(TeamPolicy):
    name = "belief"

    def __init__(self, prior: Any = None, params: PlannerParams | None = None, team: TeamParams | None = None,
                 comms: CommsModel | None = None) -> None:
        self.core = BeliefPlanner(prior=prior, params=params)
        self.params = self.core.params
        self.team = team or TeamParams()
        self.comms = comms or CommsModel()

    def reset(self, cfg: GridConfig, n: int, n_agents: int, seed: int) -> None:
        self.cfg, self.n, self.k = cfg, n, n_agents
        if n_agents == 1:
            self.core.reset(cfg, n, seed)
            return
        self.shared = SharedBelief(cfg, n, n_agents, comms=self.comms, seed=seed)
        b = self.shared.belief
        # the core supplies today's reveal rule on the team's belief rows
        self.core.reset(cfg, b.n, seed)
        density, pair = self.core._prior_cache[(cfg.width, cfg.height, cfg.distribution, cfg.n_targets)]
        if density is not None or pair is not None:
            self.shared = SharedBelief(cfg, n, n_agents, density, pair, self.comms, seed)
        self.core.belief = self.shared.belief
        self.rng = np.random.default_rng([seed, 0x7EA3])
        h, w = cfg.height, cfg.width
        self.ys, self.xs = np.mgrid[0:h, 0:w]
        self.rows = np.arange(n)
        self._brow = np.stack([self.shared.row(i) for i in range(n_agents)], axis=1)  # (n, N)

    def act(self, obs: TeamObservation) -> np.ndarray:
        if self.k == 1:
            one = Observation(views=obs.views[:, 0], maps=obs.maps[:, 0], positions=obs.positions[:, 0],
                              valid=obs.valid[:, 0], t=obs.t, active=obs.active)
            return self.core.act(one)[:, None]
        self.shared.update(obs.views, obs.positions, obs.t, obs.active)
        goal, order = self._allocate(np.asarray(obs.positions, np.int64))
        return self._moves(np.asarray(obs.positions, np.int64), goal, order, np.asarray(obs.valid))

    # ------------------------------------------------------------------ allocation
    def _allocate(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(goals (n, N, 2), the order the agents chose in (n, N))."""
        p, tp, b = self.params, self.team, self.shared.belief
        n, k, (h, w) = self.n, self.k, (self.cfg.height, self.cfg.width)
        reveal_b = self._reveal()  # (B, h, w), today's rule on every belief row
        self._reveal_b = reveal_b
        pick_b = b.sighted if not self.cfg.moving else b.target
        rev = reveal_b[self._brow].astype(np.float64)  # (n, N, h, w): each agent's own view of it
        pick = pick_b[self._brow].astype(np.float64)
        d = (np.abs(self.xs - pos[..., 0, None, None]) + np.abs(self.ys - pos[..., 1, None, None])).astype(np.float64)
        nearer = np.zeros(d.shape, bool)  # another agent strictly nearer the cell
        for i in range(k):
            for j in range(k):
                if i != j:
                    nearer[:, i] |= d[:, j] < d[:, i]
        region = np.where(nearer, tp.region, 1.0)
        noise = self.rng.random(d.shape) * 1e-6
        own = np.zeros(d.shape, bool)
        own[self.rows[:, None], np.arange(k)[None], pos[..., 1], pos[..., 0]] = True
        goal = pos.copy()
        order = np.zeros((n, k), np.int64)
        left = np.ones((n, k), bool)
        for m in range(k):
            value = (rev + p.pickup * pick) / (d + p.travel_offset) * region + noise
            value[own] = -1.0  # standing still recovers nothing new
            value[~left] = -np.inf
            flat = value.reshape(n, k * h * w)
            best = flat.argmax(axis=1)
            i, cell = np.divmod(best, h * w)
            gy, gx = np.divmod(cell, w)
            goal[self.rows, i] = np.stack([gx, gy], axis=1)
            order[:, m] = i
            left[self.rows, i] = False
            # the claim: the goal's targets are taken, its neighbourhood's reveal mostly spent
            near = (np.abs(self.ys[None] - gy[:, None, None]) <= tp.claim_radius) & \
                   (np.abs(self.xs[None] - gx[:, None, None]) <= tp.claim_radius)  # (n, h, w)
            rev = rev * np.where(near, 1.0 - tp.claim, 1.0)[:, None]
            pick[self.rows, :, gy, gx] = 0.0
        return goal, order

    def _reveal(self) -> np.ndarray:
        """Today's reveal rule on every belief row; with imperfect sharing (static targets), the
        unseen mass of cells another agent's view has shown (SharedBelief.covered: known from
        the beacons even where the view itself is late or lost) left out: whatever is there, the
        agent that saw it knows it and collects it, so it is no one else's to reveal."""
        cov = self.shared.covered
        if cov is None or self.cfg.moving:
            return self.core._reveal()
        b, p = self.shared.belief, self.params
        mass = (b.target - b.sighted) * self.core.cell_weight * ~cov
        near = _window(mass, 1, self.core._work)
        if p.outer > 0:
            near = near + p.outer * (_window(mass, 2, self.core._work) - near)
        return near

    def _moves(self, pos: np.ndarray, goal: np.ndarray, order: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """Shortest-path moves towards the goals, the one whose next view reveals more first,
        then any other valid move (a detour where separation forbids the shortest ones)."""
        h, w = self.cfg.height, self.cfg.width
        a_n = valid.shape[-1]
        nxt = pos[:, :, None, :] + DELTAS[None, None, :a_n]  # (n, N, A, 2)
        d0 = np.abs(goal - pos).sum(axis=-1)
        d1 = np.abs(goal[:, :, None] - nxt).sum(axis=-1)
        cx, cy = np.clip(nxt[..., 0], 0, w - 1), np.clip(nxt[..., 1], 0, h - 1)
        rb = self._reveal_b[self._brow]  # (n, N, h, w)
        n, k = self.n, self.k
        gain = rb[np.arange(n)[:, None, None], np.arange(k)[None, :, None], cy, cx]
        key = self.params.tie_reveal * gain + self.rng.random(gain.shape) * 1e-6
        closer = d1 < d0[..., None]
        prefs = np.where(closer, 1e6 + key, np.where(d1 == d0[..., None], 1e3 + key, key))
        return separate(pos, prefs, valid, order)
