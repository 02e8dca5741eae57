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
from .encode import egocentric_np, level_planes
from .infer import FastSearchNet
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
    #: left out of a flight's journal (autopilot_bridge.service.snapshot): the fast forward is a copy
    #: of the model's weights with work buffers, rebuilt by reset(); a fresh one has no
    #: constants in its buffer yet, which _constants_in_buffer = False (reset's) says
    journal_skip = ("fast", "_fast", "_constants_in_buffer")

    def __init__(self, model: SearchNet, name: str = "searchnet", temperature: float = 0.0,
                 fast: bool = True) -> None:
        """temperature 0: greedy. > 0: sample from softmax(logits / temperature), seeded by
        reset(); a near-greedy choice that cannot cycle forever where the belief stops changing.
        fast: a single episode (the flight's batch 1) runs the forward through
        infer.FastSearchNet, the same logits within float32 rounding without torch's
        per-operation overhead; batches (evaluation, training) run SearchNet."""
        if temperature < 0:
            raise ValueError(f"temperature must be >= 0 (got {temperature})")
        self.model = model.eval()
        self.name, self.temperature, self.use_fast = name, temperature, fast
        #: the forward used at batch 1 (None: SearchNet's), and the last one built with its key
        self.fast: FastSearchNet | None = None
        self._fast: tuple[tuple, FastSearchNet] | None = None

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        lp = self.model.cfg.level_planes
        if cfg.levels > 1 and cfg.levels > lp:
            raise ValueError(f"this search network knows {max(lp, 1)} level(s); the field has {cfg.levels} "
                             "(train one with `uavsearch train --model searchnet --levels N`)")
        self.cfg = cfg
        self.belief = BeliefState(cfg, n)
        self.rng = np.random.default_rng([seed, 0x5EA5C4])
        self.fast = self._fast_net() if self.use_fast and n == 1 else None
        self._constants_in_buffer = False  # the fast path's plane buffer holds this belief's prior

    def _fast_net(self) -> FastSearchNet:
        """The fast forward of the model's weights as they are now: kept across resets while no
        parameter was replaced or changed in place (torch counts in-place writes in _version,
        so a model trained or loaded further gets a new one)."""
        key = tuple((id(p), p._version) for p in self.model.parameters())
        if self._fast is None or self._fast[0] != key:
            self._fast = (key, FastSearchNet(self.model))
        return self._fast[1]

    def _logits(self, obs: Observation) -> np.ndarray:
        if obs.mask is not None and self.belief.mask is None:
            # a masked field: the belief's prior on its searchable cells, and its on_map plane
            # (the network's input) the mask itself; the logits are masked by obs.valid
            self.belief = BeliefState(self.cfg, self.belief.n, mask=obs.mask)
            self._constants_in_buffer = False
        self.belief.update(obs)
        lp = self.model.cfg.level_planes
        if self.fast is not None:
            buf = self.fast.input_planes(self.cfg.height, self.cfg.width)
            planes = self.belief.planes(out=buf[:, : buf.shape[1] - lp] if lp else buf,
                                        constants=not self._constants_in_buffer)
            if lp:  # the level flown, one-hot, after the belief planes
                level_planes(obs.level, 1, self.cfg.height, self.cfg.width, lp, out=buf[:, buf.shape[1] - lp:])
                planes = buf
            self._constants_in_buffer = True
            return self.fast.logits(planes, obs.positions, obs.valid)
        with torch.inference_mode():
            planes = self.belief.planes()
            if lp:
                planes = np.concatenate([planes, level_planes(obs.level, len(planes), self.cfg.height,
                                                              self.cfg.width, lp)], axis=1)
            x, mask = obs_tensors(planes, obs.positions, obs.valid, self.model.cfg.n_actions)
            return self.model(x, mask).numpy()

    def logits(self, obs: Observation) -> np.ndarray:
        """Update the belief with obs and return (n, n_actions) masked logits for every episode
        (5; 7 for a network with levels)."""
        return np.array(self._logits(obs))

    def act(self, obs: Observation) -> np.ndarray:
        z = self._logits(obs)
        if self.temperature > 0:  # Gumbel-max: a sample from softmax(z / T)
            z = z / self.temperature - np.log(-np.log(self.rng.random(z.shape)))
        a = z.argmax(axis=1)
        return np.minimum(a, self.cfg.n_actions - 1)


def load_searchnet_policy(path: str | Path, cfg: GridConfig | None = None, name: str = "searchnet",
                          temperature: float = 0.0, fast: bool = True) -> SearchNetPolicy:
    """fast=False: every batch through SearchNet's torch forward (the reference path)."""
    from ..belief import BELIEF_CHANNELS

    model, _ = load_searchnet(path)
    if model.cfg.in_channels != BELIEF_CHANNELS:
        from ..nn.checkpoint import CheckpointError

        raise CheckpointError(f"{path}: trained on {model.cfg.in_channels} belief planes, this belief has "
                              f"{BELIEF_CHANNELS}")
    return SearchNetPolicy(model, name, temperature, fast)
