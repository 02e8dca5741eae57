"""The DRQN's picture of the 3x3 view: an RGB image, as the authors drew it for their DRQN.

Cells off the map are white (the agent's only notion of the border), unvisited targets green,
targets on cells the agent has already visited (found: it stood there) red, the agent blue in
the centre, everything else black. Which targets are visited comes from the agent's own
memory of the cells it stood on, so the policy needs nothing beyond the observation.

Frames are kept compact, (n, 3, 3, 3) uint8 RGB per view cell, and blown up to the network's
input size (nearest neighbour, input_size / 3 pixels per cell) only when fed to the network:
the replay buffer stays tiny.
"""

from __future__ import annotations

import numpy as np
import torch

BLACK = (0, 0, 0)
WHITE = (255, 255, 255)  # off the map
TARGET = (0, 255, 0)  # a target not yet visited
VISITED_TARGET = (255, 0, 0)  # a target on a cell the agent has stood on
AGENT = (0, 0, 255)  # always the centre cell

_OFF = np.arange(-1, 2)


class VisitMemory:
    """Cells each episode's agent has stood on: how the agent knows which targets it found."""

    def __init__(self, n: int, width: int, height: int) -> None:
        self.visited = np.zeros((n, height, width), dtype=bool)
        self.rows = np.arange(n)

    def update(self, positions: np.ndarray, rows: np.ndarray | None = None) -> None:
        r = self.rows if rows is None else rows
        self.visited[r, positions[:, 1], positions[:, 0]] = True

    def around(self, positions: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """(m, 3, 3) bool: visited cells in each view (off-map cells False)."""
        r = self.rows if rows is None else rows
        _, h, w = self.visited.shape
        ys = positions[:, 1, None] + _OFF
        xs = positions[:, 0, None] + _OFF
        inside = ((ys >= 0) & (ys < h))[:, :, None] & ((xs >= 0) & (xs < w))[:, None, :]
        yc, xc = np.clip(ys, 0, h - 1), np.clip(xs, 0, w - 1)
        return self.visited[r[:, None, None], yc[:, :, None], xc[:, None, :]] & inside


def colour_views(views: np.ndarray, visited_around: np.ndarray) -> np.ndarray:
    """views (m, 3, 3, 3) uint8 (target, off-map, agent), visited (m, 3, 3) bool ->
    compact RGB frames (m, 3, 3, 3) uint8, channels first."""
    if views.ndim != 4 or views.shape[1:] != (3, 3, 3):
        raise ValueError(f"expected grid views (m, 3, 3, 3), got {views.shape}")
    tgt, off = views[:, 0].astype(bool), views[:, 1].astype(bool)
    cell = np.zeros(tgt.shape, dtype=np.int64)  # 0 black, 1 white, 2 target, 3 visited, 4 agent
    cell[tgt & ~visited_around] = 2
    cell[tgt & visited_around] = 3
    cell[off] = 1
    cell[:, 1, 1] = 4
    palette = np.array([BLACK, WHITE, TARGET, VISITED_TARGET, AGENT], dtype=np.uint8)
    return np.ascontiguousarray(palette[cell].transpose(0, 3, 1, 2))


def to_input(frames: np.ndarray | torch.Tensor, size: int) -> torch.Tensor:
    """Compact frames (..., 3, 3, 3) uint8 -> float tensor (..., 3, size, size) in [0, 1]."""
    if size % 3:
        raise ValueError(f"input size must be a multiple of 3, got {size}")
    x = torch.as_tensor(frames)
    k = size // 3
    x = x.repeat_interleave(k, dim=-1).repeat_interleave(k, dim=-2)
    return x.to(torch.float32) / 255.0
