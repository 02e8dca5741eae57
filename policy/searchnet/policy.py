"""The search network as a batch policy: the belief state turns observations into planes,
one forward pass decides for every running episode. It is given no placement prior: what it
knows of where targets lie it learned from the episodes it was trained on."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy
from ..belief import BeliefState
from .checkpoint import load_searchnet
from .encode import egocentric_np
from .model import SearchNet


def obs_tensors(planes: np.ndarray, positions: np.ndarray, valid: np.ndarray,
                n_actions: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(egocentric input, action mask) for a batch of belief planes."""
    x = torch.from_numpy(egocentric_np(np.asarray(planes, dtype=np.float32), positions))
    valid = np.asarray(valid, dtype=bool)
    if valid.shape[1] < n_actions:  # static worlds: no stay
        valid = np.concatenate([valid, np.zeros((len(valid), n_actions - valid.shape[1]), bool)], axis=1)
    return x, torch.from_numpy(valid)


class SearchNetPolicy(Policy):
    name = "searchnet"

    def __init__(self, model: SearchNet, name: str = "searchnet", temperature: float = 0.0) -> None:
        """temperature 0: greedy. > 0: sample from softmax(logits / temperature), seeded by
        reset(); a near-greedy choice that cannot cycle forever where the belief stops changing."""
        if temperature < 0:
            raise ValueError(f"temperature must be >= 0 (got {temperature})")
        self.model = model.eval()
        self.name, self.temperature = name, temperature

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.cfg = cfg
        self.belief = BeliefState(cfg, n)
        self.rng = np.random.default_rng([seed, 0x5EA5C4])

    @torch.inference_mode()
    def logits(self, obs: Observation) -> np.ndarray:
        """Update the belief with obs and return (n, 5) masked logits for every episode."""
        self.belief.update(obs)
        x, mask = obs_tensors(self.belief.planes(), obs.positions, obs.valid, self.model.cfg.n_actions)
        return self.model(x, mask).numpy()

    def act(self, obs: Observation) -> np.ndarray:
        z = self.logits(obs)
        if self.temperature > 0:  # Gumbel-max: a sample from softmax(z / T)
            z = z / self.temperature - np.log(-np.log(self.rng.random(z.shape)))
        a = z.argmax(axis=1)
        return np.minimum(a, self.cfg.n_actions - 1)


def load_searchnet_policy(path: str | Path, cfg: GridConfig | None = None, name: str = "searchnet",
                          temperature: float = 0.0) -> SearchNetPolicy:
    from ..belief import BELIEF_CHANNELS

    model, _ = load_searchnet(path)
    if model.cfg.in_channels != BELIEF_CHANNELS:
        from ..nn.checkpoint import CheckpointError

        raise CheckpointError(f"{path}: trained on {model.cfg.in_channels} belief planes, this belief has "
                              f"{BELIEF_CHANNELS}")
    return SearchNetPolicy(model, name, temperature)
