"""A native gymnasium VectorEnv over BatchGridWorld: num_envs episodes stepped as one batch (no
process or Python loop per sub-environment), each reset on its own when it ends (next-step
autoreset, gymnasium's default: the step after an episode's last returns its first
observation, reward 0, and ignores that action).

Registered with GridSearchEnv as gymnasium's "uavsearch/GridSearch-v0" (sim.gridworld.env):
`gymnasium.make_vec("uavsearch/GridSearch-v0", num_envs=64, vectorization_mode="vector_entry_point")`.
The paper's world only (levels = 1, no masks): a new episode is drawn for a finished row and
its state written into that row of the batch (_restart).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from .batch import BatchGridWorld
from .config import ConfigError, GridConfig
from .env import GridSearchEnv
from .episodes import Episodes, sample_episodes

#: BatchGridWorld's per-episode arrays (leading axis: the episode), written row by row on a restart
_ROW_STATE = ("agent", "t", "found", "find_moves", "visited", "met", "trail", "recoveries", "done", "_map",
              "replaced", "level", "flight_s", "found_now")


class GridSearchVectorEnv(gym.vector.VectorEnv):
    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 8, cfg: GridConfig | None = None) -> None:
        cfg = cfg or GridConfig()
        if cfg.levels != 1 or not cfg.perfect_detection:
            raise ConfigError(f"the vector env is the paper's single-height world (got levels={cfg.levels})")
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1 (got {num_envs})")
        self.cfg, self.num_envs = cfg, num_envs
        one = GridSearchEnv(cfg)
        self.single_observation_space = one.observation_space
        self.single_action_space = one.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._world: BatchGridWorld | None = None
        self._restart_next = np.zeros(num_envs, bool)

    def _draw(self, n: int) -> tuple[Episodes, int]:
        seed = int(self.np_random.integers(0, 2**62))
        return sample_episodes(self.cfg, n, seed), seed

    def _obs(self) -> dict[str, np.ndarray]:
        v, m = self._world.observe()
        return {"view": v, "map": m, "position": self._world.agent.copy()}

    def _info(self) -> dict[str, Any]:
        w = self._world
        return {"moves": w.t.copy(), "found": w.found.sum(axis=1), "flight_s": w.flight_s.copy()}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        ep, s = self._draw(self.num_envs)
        # the episodes' arrays are the batch's own copies: a restart writes a row of them
        ep = Episodes(ep.cfg, ep.agent.copy(), ep.targets.copy(), None if ep.paths is None else ep.paths.copy(), s)
        self._world = BatchGridWorld(ep, seed=s)
        self._restart_next[:] = False
        return self._obs(), self._info()

    def _restart(self, rows: np.ndarray) -> None:
        """Fresh episodes in rows (int indices): drawn, stepped nowhere, copied into the batch."""
        w = self._world
        ep, s = self._draw(len(rows))
        fresh = BatchGridWorld(ep, seed=s)
        for name in _ROW_STATE:
            getattr(w, name)[rows] = getattr(fresh, name)
        w.episodes.agent[rows] = ep.agent
        w.episodes.targets[rows] = ep.targets
        if ep.paths is not None:
            w.episodes.paths[rows] = ep.paths

    def step(self, actions):
        if self._world is None:
            raise RuntimeError("call reset() before step()")
        w = self._world
        a = np.asarray(actions, np.int64).reshape(self.num_envs).copy()
        restart = np.flatnonzero(self._restart_next)
        if len(restart):  # their action is ignored: the step returns their first observation
            self._restart(restart)
            w.done[restart] = True
        newly = w.step(a)
        w.done[restart] = False
        del w._history[:-1]  # trajectories are not kept: an endless run would grow them forever
        reward = newly.astype(np.float64)
        terminated = w.success.copy()
        truncated = w.done & ~terminated
        reward[restart] = 0.0
        terminated[restart], truncated[restart] = False, False
        self._restart_next = terminated | truncated
        return self._obs(), reward, terminated, truncated, self._info()
