"""A PettingZoo ParallelEnv over one team episode (sim.gridworld.team), for anyone who wants the
standard multi-agent API. Agents "uav_0" .. "uav_{N-1}"; each observes what GridSearchEnv's
agent observes (its 3 x 3 view, the team's visited map with its own cell marked, its cell);
reward: +1 to every agent per target the team recovers (a cooperative search: it does not
matter who finds it). Every agent terminates when all targets are found, is truncated after
t_e joint steps. Actions of every agent are applied in one joint step (the world's separation
rule refuses conflicting moves)."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from .config import GridConfig
from .env import GridSearchEnv, ansi_grid
from .episodes import sample_episodes
from .team import TeamGridWorld, check_team, team_starts


class TeamSearchParallelEnv(ParallelEnv):
    metadata = {"name": "uavsearch_team_v0", "render_modes": ["ansi"]}

    def __init__(self, cfg: GridConfig | None = None, n_agents: int = 2, render_mode: str | None = None) -> None:
        self.cfg = cfg or GridConfig()
        probe = sample_episodes(self.cfg, 1, 0)
        check_team(probe, n_agents)
        self.n_agents_ = n_agents
        self.possible_agents = [f"uav_{i}" for i in range(n_agents)]
        self.agents: list[str] = []
        self.render_mode = render_mode
        one = GridSearchEnv(self.cfg)
        self._obs_space, self._act_space = one.observation_space, one.action_space
        self._world: TeamGridWorld | None = None
        self._rng = np.random.default_rng()

    def observation_space(self, agent: str) -> spaces.Space:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Space:
        return self._act_space

    def _obs(self) -> dict[str, dict[str, np.ndarray]]:
        v, m = self._world.observe()
        return {a: {"view": v[0, i], "map": m[0, i], "position": self._world.agents[0, i].copy()}
                for i, a in enumerate(self.possible_agents)}

    def _infos(self) -> dict[str, dict[str, Any]]:
        w = self._world
        return {a: {"moves": int(w.t[0]), "found": int(w.found[0].sum()), "found_by_me": int((w.find_agent[0] == i).sum())}
                for i, a in enumerate(self.possible_agents)}

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        ep_seed = int(self._rng.integers(0, 2**62))
        ep = sample_episodes(self.cfg, 1, ep_seed)
        self._world = TeamGridWorld(ep, team_starts(ep, self.n_agents_), seed=ep_seed)
        self.agents = list(self.possible_agents)
        return self._obs(), self._infos()

    def step(self, actions: dict[str, int]):
        if self._world is None or not self.agents:
            raise RuntimeError("call reset() before step() (and after the episode ended)")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"every live agent needs an action (missing {missing})")
        a = np.array([[int(actions[x]) for x in self.possible_agents]])
        newly = float(self._world.step(a)[0])
        won = bool(self._world.success[0])
        over = bool(self._world.done[0])
        obs, infos = self._obs(), self._infos()
        rewards = {x: newly for x in self.agents}
        terms = {x: won for x in self.agents}
        truncs = {x: over and not won for x in self.agents}
        if over:
            self.agents = []
        return obs, rewards, terms, truncs, infos

    def render(self) -> str | None:
        if self._world is None or self.render_mode != "ansi":
            return None
        w = self._world
        return ansi_grid(w, [(int(x), int(y), str(i % 10)) for i, (x, y) in enumerate(w.agents[0])])
