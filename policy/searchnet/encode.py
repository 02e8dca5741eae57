"""Belief planes -> the network's input: the whole field re-centred on the agent.

Why egocentric: the decision is about directions from the agent, and a field of any size
becomes a (2h - 1, 2w - 1) window with the agent at its centre, so one network serves 10 x 10
and 20 x 20 alike. Three planes are added: on-field (the borders, hence the absolute position
that a placement prior depends on) and the offsets dx, dy in cells (scaled by a constant, not
by the field size, so a distance means the same on every field).
"""

from __future__ import annotations

import numpy as np
import torch

EXTRA_PLANES = 3
OFFSET_SCALE = 8.0


def egocentric(planes: torch.Tensor, pos: torch.Tensor) -> torch.Tensor:
    """planes (B, C, h, w) float, pos (B, 2) long cells (x, y) -> (B, C + 3, 2h - 1, 2w - 1)."""
    b, c, h, w = planes.shape
    if pos.shape != (b, 2):
        raise ValueError(f"positions must be ({b}, 2) (got {tuple(pos.shape)})")
    ones = torch.ones((b, 1, h, w), dtype=planes.dtype, device=planes.device)
    padded = torch.nn.functional.pad(torch.cat([planes, ones], dim=1), (w - 1, w - 1, h - 1, h - 1))
    rows = pos[:, 1, None] + torch.arange(2 * h - 1, device=planes.device)  # (B, 2h-1)
    cols = pos[:, 0, None] + torch.arange(2 * w - 1, device=planes.device)
    bi = torch.arange(b, device=planes.device)[:, None, None]
    crop = padded.permute(0, 2, 3, 1)[bi, rows[:, :, None], cols[:, None, :]].permute(0, 3, 1, 2)
    dy = (torch.arange(2 * h - 1, device=planes.device, dtype=planes.dtype) - (h - 1)) / OFFSET_SCALE
    dx = (torch.arange(2 * w - 1, device=planes.device, dtype=planes.dtype) - (w - 1)) / OFFSET_SCALE
    coords = torch.stack(torch.broadcast_tensors(dx[None, :], dy[:, None]), dim=0)
    return torch.cat([crop, coords.expand(b, 2, 2 * h - 1, 2 * w - 1)], dim=1)


def action_mask(valid: torch.Tensor, n_actions: int) -> torch.Tensor:
    """valid (B, A) bool with A = 4 (static: no stay) or 5 -> (B, n_actions) bool."""
    if valid.shape[1] == n_actions:
        return valid
    pad = torch.zeros((valid.shape[0], n_actions - valid.shape[1]), dtype=torch.bool, device=valid.device)
    return torch.cat([valid, pad], dim=1)


def egocentric_np(planes: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """The same window in numpy, for decisions: at batch 1 (the flight) one slice copy instead of
    a dozen small torch ops. planes (B, C, h, w) float32, pos (B, 2) int cells (x, y)."""
    b, c, h, w = planes.shape
    out = np.zeros((b, c + EXTRA_PLANES, 2 * h - 1, 2 * w - 1), dtype=np.float32)
    out[:, c + 1] = (np.arange(2 * w - 1, dtype=np.float32) - (w - 1)) / OFFSET_SCALE
    out[:, c + 2] = ((np.arange(2 * h - 1, dtype=np.float32) - (h - 1)) / OFFSET_SCALE)[:, None]
    pos = np.asarray(pos, dtype=np.int64)
    if b == 1:
        x, y = int(pos[0, 0]), int(pos[0, 1])
        out[0, :c, h - 1 - y: 2 * h - 1 - y, w - 1 - x: 2 * w - 1 - x] = planes[0]
        out[0, c, h - 1 - y: 2 * h - 1 - y, w - 1 - x: 2 * w - 1 - x] = 1.0
        return out
    rows = (h - 1 - pos[:, 1])[:, None] + np.arange(h)  # where each field row lands in the window
    cols = (w - 1 - pos[:, 0])[:, None] + np.arange(w)
    bi = np.arange(b)[:, None, None]
    body = np.concatenate([planes, np.ones((b, 1, h, w), dtype=np.float32)], axis=1).transpose(0, 2, 3, 1)
    view = out.transpose(0, 2, 3, 1)
    view[bi, rows[:, :, None], cols[:, None, :], : c + 1] = body
    return out


def level_planes(level: np.ndarray | None, n: int, h: int, w: int, planes: int,
                 out: np.ndarray | None = None) -> np.ndarray:
    """(n, planes, h, w) float32 one-hot of the level flown (level 1 -> plane 0): the level as
    the network's input, on the field's cells (the crop leaves it 0 off the field like every
    field plane). level (n,) in 1..planes, None: level 1 (a field without levels)."""
    lv = np.ones(n, np.int64) if level is None else np.asarray(level, np.int64).reshape(n)
    if (lv < 1).any() or (lv > planes).any():
        raise ValueError(f"levels must be in 1..{planes} for this network (got {lv.min()}..{lv.max()})")
    if out is None:
        out = np.empty((n, planes, h, w), np.float32)
    out[...] = 0.0
    out[np.arange(n), lv - 1] = 1.0
    return out
