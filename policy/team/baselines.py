"""The team baselines (issue 29): N independent single-agent planners, and a lawnmower over the
field cut in N strips. Both keep the team's separation rule (policy.team.base.separate), so
what they lose against the team planner is the shared belief and the allocation, not bumps."""

from __future__ import annotations

import numpy as np

from sim.gridworld import GridConfig

from ..base import Observation, Policy
from ..baselines.lawnmower import serpentine
from ..groundtruth.legs import step_towards
from .base import TeamObservation, TeamPolicy, separate


class IndependentTeam(TeamPolicy):
    """N copies of a single-agent policy, one per agent, each with its own belief fed its own
    observations only (today's behaviour, N times in one field): one batched policy over
    n * N rows (row e * N + i: agent i of episode e). An agent does not know what the others
    found; a target another agent recovered still shows in its view, and it goes for it."""

    def __init__(self, policy: Policy, name: str | None = None) -> None:
        self.inner = policy
        self.name = name or f"{policy.name}-independent"

    def reset(self, cfg: GridConfig, n: int, n_agents: int, seed: int) -> None:
        self.n, self.k = n, n_agents
        self.inner.reset(cfg, n * n_agents, seed)

    def act(self, obs: TeamObservation) -> np.ndarray:
        n, k = self.n, self.k
        flat = Observation(
            views=obs.views.reshape(n * k, *obs.views.shape[2:]),
            maps=obs.maps.reshape(n * k, *obs.maps.shape[2:]),
            positions=obs.positions.reshape(n * k, 2),
            valid=obs.valid.reshape(n * k, -1),
            t=np.repeat(obs.t, k), active=np.repeat(obs.active, k))
        want = np.asarray(self.inner.act(flat), np.int64).reshape(n, k)
        a_n = obs.valid.shape[-1]
        prefs = np.where(np.arange(a_n) == want[..., None], 1.0, 0.0)
        return separate(obs.positions, prefs, obs.valid)


class StripLawnmower(TeamPolicy):
    """The field cut in N vertical strips of near-equal width; the agents, sorted by column,
    take the strips from left to right; each sweeps its strip's rows (boustrophedon) from the
    strip's corner nearest to it, as today's lawnmower sweeps the whole field."""

    name = "lawnmower-strips"

    def reset(self, cfg: GridConfig, n: int, n_agents: int, seed: int) -> None:
        if n_agents > cfg.width:
            raise ValueError(f"{n_agents} strips need a grid at least {n_agents} wide (got {cfg.width})")
        self.cfg, self.n, self.k = cfg, n, n_agents
        self.rng = np.random.default_rng([seed, 0x57219])
        edges = np.linspace(0, cfg.width, n_agents + 1).round().astype(int)
        self.edges = edges
        #: per strip s and corner c: the route (L, 2), padded by repeating its last cell
        size = int(np.diff(edges).max()) * cfg.height
        self.routes = np.zeros((n_agents, 4, size, 2), np.int64)
        self.length = np.zeros(n_agents, np.int64)
        for s in range(n_agents):
            sw = int(edges[s + 1] - edges[s])
            for c in range(4):
                r = serpentine(sw, cfg.height, c) + np.array([edges[s], 0])
                self.routes[s, c, : len(r)] = r
                self.routes[s, c, len(r):] = r[-1]
            self.length[s] = sw * cfg.height
        self.strip: np.ndarray | None = None
        self.corner: np.ndarray | None = None
        self.idx = np.zeros((n, n_agents), np.int64)

    def act(self, obs: TeamObservation) -> np.ndarray:
        pos = np.asarray(obs.positions, np.int64)
        n, k = self.n, self.k
        if self.strip is None:
            rank = np.argsort(pos[..., 0] * k + np.arange(k), axis=1, kind="stable")
            self.strip = np.empty((n, k), np.int64)
            self.strip[np.arange(n)[:, None], rank] = np.arange(k)[None]
            firsts = self.routes[self.strip, :, 0]  # (n, N, 4, 2)
            dist = np.abs(firsts - pos[:, :, None]).sum(-1) + self.rng.random((n, k, 4)) * 0.5
            self.corner = dist.argmin(axis=2)
        route = self.routes[self.strip, self.corner]  # (n, N, L, 2)
        last = self.length[self.strip] - 1
        e, a = np.arange(n)[:, None], np.arange(k)[None]
        here = np.all(route[e, a, self.idx] == pos, axis=-1) & (self.idx < last)
        self.idx[here] += 1
        goal = route[e, a, self.idx]
        want = step_towards(pos.reshape(-1, 2), goal.reshape(-1, 2), self.rng).reshape(n, k)
        a_n = obs.valid.shape[-1]
        prefs = np.where(np.arange(a_n) == want[..., None], 1.0, 0.0) + self.rng.random((n, k, a_n)) * 1e-3
        return separate(pos, prefs, obs.valid)
