"""Networks as batch policies: one forward pass decides for every running episode."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from sim.gridworld import Episodes, GridConfig

from ..base import Observation, Policy
from ..loops import LoopGuard
from .encode import to_tensors


class NetworkPolicy(Policy):
    """Argmax of the network's output for every active episode, one forward pass per step.

    Off-map choices are the world's to replace (a random valid move); loop detection is the
    `LoopGuard` wrapper's job, so this class stays the bare network."""

    def __init__(self, model: nn.Module, name: str = "dualstream", device: str = "cpu") -> None:
        self.model = model.to(device).eval()
        self.name, self.device = name, device

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.n_actions = cfg.n_actions

    @torch.inference_mode()
    def scores(self, views: np.ndarray, maps: np.ndarray) -> np.ndarray:
        """(n, A) network outputs (logits; log-probabilities for the SSN) for n observations."""
        v, m = to_tensors(views, maps, self.device)
        return self.model(v, m).float().cpu().numpy()

    def decide(self, view: np.ndarray, grid_map: np.ndarray) -> int:
        """One decision from one observation (view (C,H,W), map (C,h,w)): the policy service's call."""
        return int(self.scores(view[None], grid_map[None])[0].argmax())

    def act(self, obs: Observation) -> np.ndarray:
        a = np.zeros(len(obs.positions), dtype=np.int64)
        idx = np.flatnonzero(obs.active)
        if idx.size:
            a[idx] = self.scores(obs.views[idx], obs.maps[idx]).argmax(axis=1)
        return a


def shipped_checkpoint(name: str = "dualstream_static_random") -> Path:
    return Path(__file__).resolve().parent.parent / "checkpoints" / f"{name}.pt"


def load_shipped_policy(cfg: GridConfig | None = None, model: str = "dualstream",
                        device: str = "cpu") -> Policy:
    """The shipped network for the static random setting (`eval --policy dualstream`, the demo):
    a NetworkPolicy under LoopGuard, as the paper tests it."""
    return load_policy(shipped_checkpoint(f"{model}_static_random"), cfg=cfg, device=device, name=model)


def load_policy(
    checkpoint: str | Path | None = None,
    cfg: GridConfig | None = None,
    loop_guard: bool | None = None,
    device: str = "cpu",
    name: str | None = None,
) -> Policy:
    """A network policy from a checkpoint (the shipped one by default), under loop detection
    for static targets as in the paper (Section V-B; disabled for moving targets, VI-F)."""
    from .checkpoint import load_model

    path = Path(checkpoint) if checkpoint is not None else shipped_checkpoint()
    model, doc = load_model(path)
    mc = doc["model_config"]
    if cfg is not None:
        if cfg.n_actions != mc.n_actions or (cfg.map_channels, cfg.height, cfg.width) != tuple(mc.map_shape):
            raise ValueError(
                f"{path} was trained for maps {mc.map_shape} and {mc.n_actions} actions; "
                f"this config has maps {(cfg.map_channels, cfg.height, cfg.width)} and {cfg.n_actions}"
            )
    policy: Policy = NetworkPolicy(model, name or mc.model, device)
    guard = (mc.n_actions == 4) if loop_guard is None else loop_guard
    return LoopGuard(policy) if guard else policy
