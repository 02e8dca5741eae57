"""searchnet as a decentralised team policy (issue 29): every agent runs the same network on
the team's shared belief, centred on its own cell, with one more input plane marking where its
teammates are. One network serves any team size N and any field size.

The input of agent i (`team_planes`): the belief planes of the rows agent i plans on
(policy.belief.shared.SharedBelief.row: the one shared belief, or its own copy where sharing
is delayed or lossy) with the `agent` plane set to agent i's own cell, then the teammates'
plane: 1 on every other agent's cell (known to the whole team from the beacons, as the
separation rule needs; docs/fleet.md). Nothing else: no teammate's goal or plan, so what an
agent decides on is what the shared belief and the positions give it. A lone agent's teammate
plane is 0; a single-agent network (SearchNetConfig.team_planes = 0, the checkpoints from
before teams) has no such plane and is run at N = 1 as today's `searchnet`, the same object.

No conflicts, guaranteed by construction: the N agents' logits go through the team policies'
separation rule (policy.team.base.separate) in a fixed priority order 0..N-1: agent i takes its
best valid move whose cell is neither the current cell of an agent after it nor the cell an
agent before it took, so no two agents share a cell and none swap. Decentralised, because with
the shared belief and the positions every agent can run the network for the agents before it
and replay that rule itself (greedy decisions are deterministic), so no message beyond the
beacons is needed; under a lossy link the copies differ and the chosen moves would travel with
the beacons (a few bits). Only an agent boxed in (a corner with both neighbours held) proposes
a move the world then refuses (it stays: `blocked`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from sim.gridworld import GridConfig

from ..belief.shared import CommsModel, SharedBelief
from ..belief.state import PLANE_NAMES
from ..team.base import TeamObservation, TeamPolicy, separate
from .encode import egocentric_np
from .model import SearchNet

#: the belief's plane of the agent's own cell, replaced per agent
AGENT_PLANE = PLANE_NAMES.index("agent")


def teammates_planes(positions: np.ndarray, h: int, w: int, planes: int = 1) -> np.ndarray:
    """(n, N, planes, h, w) float32 for agent i of episode e: plane 0, 1 on the other agents'
    cells; plane 1 (planes = 2), 1 where another agent is strictly nearer (Manhattan) than
    agent i: the team planner's regions, from the positions alone."""
    pos = np.asarray(positions, np.int64)
    n, k = pos.shape[:2]
    out = np.zeros((n, k, planes, h, w), np.float32)
    e = np.arange(n)
    for i in range(k):  # N is small: loops over agent pairs, vectorised over episodes
        for j in range(k):
            if j != i:
                out[e, i, 0, pos[:, j, 1], pos[:, j, 0]] = 1.0
    if planes > 1:
        ys, xs = np.mgrid[0:h, 0:w]
        d = np.abs(xs - pos[..., 0, None, None]) + np.abs(ys - pos[..., 1, None, None])  # (n, N, h, w)
        for i in range(k):
            others = [j for j in range(k) if j != i]
            if others:
                out[:, i, 1] = (d[:, others].min(axis=1) < d[:, i]).astype(np.float32)
    return out


def team_planes(belief_planes: np.ndarray, rows: np.ndarray, positions: np.ndarray, planes: int = 1) -> np.ndarray:
    """The decentralised input: (n * N, C + planes, h, w) float32, row e * N + i for agent i of
    episode e. belief_planes (B, C, h, w) of the team's belief, rows (n, N) the belief row each
    agent plans on, positions (n, N, 2) cells (x, y); planes: the network's team_planes."""
    pos = np.asarray(positions, np.int64)
    n, k = pos.shape[:2]
    _, c, h, w = belief_planes.shape
    out = np.empty((n, k, c + planes, h, w), np.float32)
    out[:, :, :c] = belief_planes[rows]
    out[:, :, AGENT_PLANE] = 0.0
    out[np.arange(n)[:, None], np.arange(k)[None], AGENT_PLANE, pos[..., 1], pos[..., 0]] = 1.0
    out[:, :, c:] = teammates_planes(pos, h, w, planes)
    return out.reshape(n * k, c + planes, h, w)


def padded_valid(valid: np.ndarray, n_actions: int) -> np.ndarray:
    """(..., A) valid moves -> (..., n_actions) (static worlds: no stay, the 5th is False)."""
    v = np.asarray(valid, bool)
    if v.shape[-1] == n_actions:
        return v
    pad = np.zeros((*v.shape[:-1], n_actions - v.shape[-1]), bool)
    return np.concatenate([v, pad], axis=-1)


def team_logits(model: SearchNet, planes: np.ndarray, positions: np.ndarray, valid: np.ndarray,
                chunk: int = 1024) -> np.ndarray:
    """(m, n_actions) masked logits of m agent inputs (planes (m, C + 1, h, w), positions (m, 2),
    valid (m, A)); in chunks, so a batch of 20 x 20 windows stays small."""
    out = np.empty((len(planes), model.cfg.n_actions), np.float32)
    mask = torch.from_numpy(padded_valid(valid, model.cfg.n_actions))
    with torch.inference_mode():
        for s in range(0, len(planes), chunk):
            x = torch.from_numpy(egocentric_np(planes[s: s + chunk], positions[s: s + chunk]))
            out[s: s + chunk] = model(x, mask[s: s + chunk]).numpy()
    return out


class AgentLoops:
    """The paper's loop guard (policy.loops.LoopGuard) for each agent of a team: a queue of the
    agent's last `window` cells; a cell occurring alpha times in it starts the fallback, the
    vote towards cells no agent of the team has stood on (the team's positions are known to
    all), until a move lands on such a cell. Why: a greedy network can cycle where the belief
    stops changing (one agent of a team oscillating between two cells was the longest tail in
    validation); the fallback only reorders the agent's preferences, so the separation still
    decides the joint move."""

    def __init__(self, cfg: GridConfig, n: int, k: int, seed: int, alpha: int = 3, window: int = 40) -> None:
        self.n, self.k, self.alpha, self.window = n, k, alpha, window
        self.rng = np.random.default_rng([seed, 0x100F, k])
        self.queue = np.full((n * k, window, 2), -1, np.int64)
        self.qlen = np.zeros(n * k, np.int64)
        self.visited = np.zeros((n, cfg.height, cfg.width), bool)
        self.fallback = np.zeros(n * k, bool)
        self.count = np.zeros(n * k, np.int64)
        self.episode = np.repeat(np.arange(n), k)

    def __call__(self, prefs: np.ndarray, positions: np.ndarray, active: np.ndarray) -> np.ndarray:
        """prefs (n, N, A) -> the same with each agent in the fallback preferring its vote."""
        from ..loops import queue_step, vote

        pos = np.asarray(positions, np.int64).reshape(-1, 2)
        act, e = np.repeat(np.asarray(active, bool), self.k), self.episode
        new_cell = ~self.visited[e, pos[:, 1], pos[:, 0]]
        self.visited[e[act], pos[act, 1], pos[act, 0]] = True
        queue_step(self.queue, self.qlen, self.fallback, self.count, pos, act, new_cell, self.alpha)
        fb = np.flatnonzero(act & self.fallback)
        if fb.size == 0:
            return prefs
        a = vote(pos[fb], self.visited[e[fb]], self.rng)
        out = prefs.reshape(self.n * self.k, -1).copy()
        ok = a < out.shape[1]
        out[fb[ok], a[ok]] += 1e6  # nothing left unvisited (Action.N): the network's own choice
        return out.reshape(prefs.shape)


class TeamSearchNet(TeamPolicy):
    """The decentralised team searchnet (module docstring). temperature > 0 samples each agent's
    preferences from softmax(logits / T) (seeded by reset), for exploration in training.
    loop_guard (None: on for static targets, as for today's searchnet): AgentLoops."""

    name = "searchnet"

    def __init__(self, model: SearchNet, temperature: float = 0.0, comms: CommsModel | None = None,
                 single: Any = None, loop_guard: bool | None = None) -> None:
        """single: the policy run at N = 1 for a single-agent network (today's `searchnet`)."""
        self.loop_guard = loop_guard
        if temperature < 0:
            raise ValueError(f"temperature must be >= 0 (got {temperature})")
        if model.cfg.level_planes or model.cfg.privileged_channels:
            raise ValueError("a team searchnet decides at one height from the belief alone "
                             f"(got level_planes {model.cfg.level_planes}, privileged {model.cfg.privileged_channels})")
        self.model = model.eval()
        self.temperature = temperature
        self.comms = comms or CommsModel()
        self.single = single

    def reset(self, cfg: GridConfig, n: int, n_agents: int, seed: int) -> None:
        if cfg.levels > 1:
            raise ValueError(f"the team searchnet flies one height (got levels {cfg.levels})")
        if n_agents > 1 and not self.model.cfg.team_planes:
            raise ValueError("this search network has no teammates' plane: train one with "
                             "`uavsearch train --model searchnet --agents N`")
        self.cfg, self.n, self.k = cfg, n, n_agents
        self.rng = np.random.default_rng([seed, 0x7EA45E])
        if n_agents == 1 and not self.model.cfg.team_planes:
            if self.single is None:
                from ..searchnet.policy import SearchNetPolicy

                self.single = SearchNetPolicy(self.model)
            self.single.reset(cfg, n, seed)
            return
        self.shared = SharedBelief(cfg, n, n_agents, comms=self.comms, seed=seed)
        guard = (not cfg.moving) if self.loop_guard is None else self.loop_guard
        self.loops = AgentLoops(cfg, n, n_agents, seed) if guard else None
        self._brow = np.stack([self.shared.row(i) for i in range(n_agents)], axis=1)  # (n, N)

    def inputs(self, obs: TeamObservation) -> np.ndarray:
        """Fold the step's views into the team's belief; (n * N, C + 1, h, w) agent inputs."""
        self.shared.update(obs.views, obs.positions, obs.t, obs.active)
        return team_planes(self.shared.belief.planes(), self._brow, obs.positions, self.model.cfg.team_planes)

    def preferences(self, obs: TeamObservation) -> np.ndarray:
        """(n, N, n_actions) each agent's masked logits (sampled with a temperature)."""
        n, k = self.n, self.k
        planes = self.inputs(obs)
        z = team_logits(self.model, planes, np.asarray(obs.positions).reshape(n * k, 2),
                        np.asarray(obs.valid).reshape(n * k, -1)).reshape(n, k, -1)
        if self.temperature > 0:  # Gumbel-max: a sample from softmax(z / T)
            z = z / self.temperature - np.log(-np.log(self.rng.random(z.shape)))
        return z

    def act(self, obs: TeamObservation) -> np.ndarray:
        if self.k == 1 and not self.model.cfg.team_planes:
            from ..base import Observation

            one = Observation(views=obs.views[:, 0], maps=obs.maps[:, 0], positions=obs.positions[:, 0],
                              valid=obs.valid[:, 0], t=obs.t, active=obs.active)
            return np.asarray(self.single.act(one), np.int64)[:, None]
        valid = np.asarray(obs.valid)
        z = self.preferences(obs)[..., : valid.shape[-1]]
        if self.loops is not None:
            z = self.loops(z, obs.positions, obs.active)
        return separate(np.asarray(obs.positions, np.int64), z, valid)


def widen_for_team(model: SearchNet, planes: int = 1) -> SearchNet:
    """A single-agent network as a team network that decides exactly as it did: the teammates'
    planes are added to the first layer with zero weights (fine-tuning then learns them)."""
    from dataclasses import replace

    from .config import SearchNetConfig

    cfg: SearchNetConfig = model.cfg
    if cfg.team_planes:
        return model
    new = SearchNet(replace(cfg, team_planes=planes))
    sd = {k: v.clone() for k, v in model.state_dict().items()}
    w = sd["conv1.weight"]
    at = cfg.in_channels + cfg.level_planes  # the team plane's place: after belief and level planes
    sd["conv1.weight"] = torch.cat([w[:, :at], torch.zeros_like(w[:, :planes]), w[:, at:]], dim=1)
    new.load_state_dict(sd)
    return new.eval()


def load_team_searchnet(path: str | Path, temperature: float = 0.0, comms: CommsModel | None = None) -> TeamSearchNet:
    from .checkpoint import load_searchnet

    model, _ = load_searchnet(path)
    return TeamSearchNet(model, temperature, comms)
