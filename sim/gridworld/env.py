"""A gymnasium Env over one grid-world episode, for anyone who wants the standard RL API.
Reward: +1 per newly recovered target (the DRQN baseline's reward), nothing else."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .batch import BatchGridWorld
from .config import GridConfig
from .episodes import sample_episodes
from .observations import LEVEL_VIEW_CHANNELS


class GridSearchEnv(gym.Env):
    metadata = {"render_modes": ["ansi"]}

    def __init__(self, cfg: GridConfig | None = None, render_mode: str | None = None) -> None:
        self.cfg = cfg or GridConfig()
        self.render_mode = render_mode
        c, h, w = self.cfg.map_channels, self.cfg.height, self.cfg.width
        self.action_space = spaces.Discrete(self.cfg.n_actions)
        obs = {
            "view": spaces.Box(0, 1, shape=(3, 3, 3), dtype=np.uint8),
            "map": spaces.Box(0.0, float(max(10, self.cfg.trail_value)), shape=(c, h, w), dtype=np.float32),
            "position": spaces.Box(0, max(w, h) - 1, shape=(2,), dtype=np.int64),
        }
        if self.cfg.levels > 1:  # the highest level's window of detections, and the level flown
            k = 2 * self.cfg.view_radius + 1
            obs["view"] = spaces.Box(0, 1, shape=(LEVEL_VIEW_CHANNELS, k, k), dtype=np.uint8)
            obs["level"] = spaces.Discrete(self.cfg.levels, start=1)
        self.observation_space = spaces.Dict(obs)
        self._world: BatchGridWorld | None = None

    def _obs(self) -> dict[str, np.ndarray]:
        assert self._world is not None
        v, m = self._world.observe()
        out = {"view": v[0], "map": m[0], "position": self._world.agent[0].copy()}
        if self.cfg.levels > 1:
            out["level"] = int(self._world.level[0])
        return out

    def _info(self) -> dict[str, Any]:
        assert self._world is not None
        return {"moves": int(self._world.t[0]), "found": int(self._world.found[0].sum()),
                "flight_s": float(self._world.flight_s[0])}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        ep_seed = int(self.np_random.integers(0, 2**62))
        self._world = BatchGridWorld(sample_episodes(self.cfg, 1, ep_seed), seed=ep_seed)
        return self._obs(), self._info()

    def step(self, action):
        if self._world is None:
            raise RuntimeError("call reset() before step()")
        if self._world.done[0]:
            raise RuntimeError("episode is over; call reset()")
        newly = self._world.step(np.array([int(action)]))
        terminated = bool(self._world.success[0])
        truncated = bool(self._world.done[0] and not terminated)
        return self._obs(), float(newly[0]), terminated, truncated, self._info()

    def render(self) -> str | None:
        if self._world is None or self.render_mode != "ansi":
            return None
        w = self._world
        return ansi_grid(w, [(int(w.agent[0, 0]), int(w.agent[0, 1]), "A")])


def ansi_grid(world, agents: list[tuple[int, int, str]]) -> str:
    """Episode 0 of a batched world as text: visited 'o', unfound 'T', found 'x', then each
    agent's (x, y, label) on top (the single agent's 'A', a team's indices)."""
    h, w_ = world.visited.shape[1:]
    grid = np.full((h, w_), ".", dtype="<U1")
    grid[world.visited[0]] = "o"
    for (x, y), f in zip(world.targets()[0], world.found[0], strict=True):
        grid[y, x] = "x" if f else "T"
    for x, y, label in agents:
        grid[y, x] = label
    return "\n".join("".join(r) for r in grid)


#: gymnasium's id for the grid world: `gymnasium.make(ENV_ID, cfg=GridConfig(...))` gives GridSearchEnv,
#: `gymnasium.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point")` the native
#: batched GridSearchVectorEnv (sim.gridworld.vector)
ENV_ID = "uavsearch/GridSearch-v0"
if ENV_ID not in gym.registry:
    gym.register(ENV_ID, entry_point="sim.gridworld.env:GridSearchEnv",
                 vector_entry_point="sim.gridworld.vector:GridSearchVectorEnv")
