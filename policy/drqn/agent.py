"""The trained DRQN as a batch policy: LSTM state per episode, epsilon 0.01 at test, a wall bump
leaves it in place (its training world)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy
from .model import Drqn, drqn_view
from .train import found_in_view, load_drqn


class DrqnPolicy(Policy):
    name = "drqn"
    off_map = "stay"  # tested in the world it was trained in, as the authors did

    def __init__(self, net: Drqn, image: int = 84, epsilon: float = 0.01) -> None:
        self.net, self.image, self.epsilon = net.eval(), image, epsilon

    @classmethod
    def load(cls, path: str | Path) -> DrqnPolicy:
        net, doc = load_drqn(path)
        return cls(net, doc["drqn_config"]["image"], doc["drqn_config"]["test_epsilon"])

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.rng = np.random.default_rng([seed, 0xD79])
        self.state = None
        self.n_actions = cfg.n_actions

    @torch.inference_mode()
    def act(self, obs: Observation) -> np.ndarray:
        found = found_in_view(obs.views, obs.maps, obs.positions)
        frames = torch.from_numpy(drqn_view(obs.views, found, self.image))[:, None]
        q, self.state = self.net(frames, self.state)
        a = q[:, 0].argmax(dim=1).numpy()
        explore = self.rng.random(len(a)) < self.epsilon
        return np.where(explore, self.rng.integers(0, self.n_actions, len(a)), a)
