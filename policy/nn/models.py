"""The dual-stream network (paper Fig. 1) and the split-stream baseline (SSN).

Both take raw observation tensors (uint8 views, maps as stored) and normalise inside, so the
exported model is the whole decision function and nothing outside can scale inputs wrongly.
"""

from __future__ import annotations

import torch
from torch import nn

from .config import ModelConfig
from .encode import normalise
from .streams import STREAMS, init_weights


class DualStream(nn.Module):
    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        visual, mapper = STREAMS[cfg.arch]
        self.visual, nv = visual(cfg.view_shape)
        self.mapper, nm = mapper(cfg.map_shape)
        hidden = 256 if cfg.arch == "small" else 0
        self.head = (
            nn.Sequential(nn.Linear(nv + nm, hidden), nn.ReLU(), nn.Linear(hidden, cfg.n_actions))
            if hidden
            else nn.Linear(nv + nm, cfg.n_actions)
        )
        self.register_buffer("view_scale", torch.tensor(float(cfg.view_scale)))
        self.register_buffer("map_scale", torch.tensor(float(cfg.map_scale)))
        init_weights(self)

    def forward(self, view: torch.Tensor, grid_map: torch.Tensor) -> torch.Tensor:
        """Logits over the actions."""
        v, m = normalise(view, grid_map, self.view_scale, self.map_scale)
        return self.head(torch.cat([self.visual(v), self.mapper(m)], dim=1))

    def probabilities(self, view: torch.Tensor, grid_map: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self(view, grid_map), dim=1)

    def loss(self, view: torch.Tensor, grid_map: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        logits = self(view, grid_map)
        return nn.functional.cross_entropy(logits, target), logits


class SplitStream(nn.Module):
    """SSN: each stream with its own softmax head and loss, trained jointly; at prediction the
    two softmax outputs are summed and normalised (paper Section V-D 3)."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        visual, mapper = STREAMS[cfg.arch]
        self.visual, nv = visual(cfg.view_shape)
        self.mapper, nm = mapper(cfg.map_shape)
        self.view_head = nn.Linear(nv, cfg.n_actions)
        self.map_head = nn.Linear(nm, cfg.n_actions)
        self.register_buffer("view_scale", torch.tensor(float(cfg.view_scale)))
        self.register_buffer("map_scale", torch.tensor(float(cfg.map_scale)))
        init_weights(self)

    def streams(self, view: torch.Tensor, grid_map: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        v, m = normalise(view, grid_map, self.view_scale, self.map_scale)
        return self.view_head(self.visual(v)), self.map_head(self.mapper(m))

    def forward(self, view: torch.Tensor, grid_map: torch.Tensor) -> torch.Tensor:
        """Log of the normalised sum of both softmaxes (so argmax and CE-style use both work)."""
        lv, lm = self.streams(view, grid_map)
        p = (torch.softmax(lv, dim=1) + torch.softmax(lm, dim=1)) / 2
        return torch.log(p.clamp_min(1e-12))

    def probabilities(self, view: torch.Tensor, grid_map: torch.Tensor) -> torch.Tensor:
        return torch.exp(self(view, grid_map))

    def loss(self, view: torch.Tensor, grid_map: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        lv, lm = self.streams(view, grid_map)
        loss = nn.functional.cross_entropy(lv, target) + nn.functional.cross_entropy(lm, target)
        p = (torch.softmax(lv, dim=1) + torch.softmax(lm, dim=1)) / 2
        return loss, torch.log(p.clamp_min(1e-12))


def build_model(cfg: ModelConfig) -> nn.Module:
    return DualStream(cfg) if cfg.model == "dualstream" else SplitStream(cfg)
