"""Uniformly random valid moves (with 'stay' where the config has it): the floor any search
policy must beat."""

from __future__ import annotations

import numpy as np

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy, random_valid


class RandomPolicy(Policy):
    name = "random"

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.rng = np.random.default_rng([seed, 0x7A2D])
        self.n_actions = cfg.n_actions

    def act(self, obs: Observation) -> np.ndarray:
        return random_valid(obs.valid[:, : self.n_actions], self.rng)
