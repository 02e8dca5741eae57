"""Observation -> network input, in one place.

The networks take the observation as stored (views uint8, maps float32 or uint8) and call
`normalise` first thing in `forward`, so an exported TorchScript file is the whole decision
function: the policy service cannot scale inputs differently from training.
Views become [0, 1] (the grid view holds 0/1 per channel, rendered frames 0..255); maps are
divided by their largest value (10 for the spatial and +M maps, 50 for the spatiotemporal one).
"""

from __future__ import annotations

import numpy as np
import torch

GRID_VIEW_SCALE = 1.0
RENDERED_VIEW_SCALE = 255.0
STATIC_MAP_SCALE = 10.0  # the agent's own cell
SPATIOTEMPORAL_MAP_SCALE = 50.0  # the trail's fresh value


def view_scale_for(rendered: bool) -> float:
    return RENDERED_VIEW_SCALE if rendered else GRID_VIEW_SCALE


def map_scale_for(channels: int) -> float:
    """One channel: spatial or +M (values 0, 1, 5, 10); two: the spatiotemporal trail/recoveries."""
    if channels not in (1, 2):
        raise ValueError(f"maps have 1 (spatial, +M) or 2 (spatiotemporal) channels, not {channels}")
    return SPATIOTEMPORAL_MAP_SCALE if channels == 2 else STATIC_MAP_SCALE


def normalise(view: torch.Tensor, grid_map: torch.Tensor, view_scale: torch.Tensor,
              map_scale: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    return view.float() / view_scale, grid_map.float() / map_scale


def to_tensors(views: np.ndarray, maps: np.ndarray, device: torch.device | str = "cpu"
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """Numpy observations as the tensors the networks take (no copy when already contiguous)."""
    v = torch.from_numpy(np.ascontiguousarray(views))
    m = torch.from_numpy(np.ascontiguousarray(maps, dtype=np.float32))
    return v.to(device), m.to(device)
