"""Masked fields: which cells of the grid can be searched, per episode, and the distances on them.

A mask is a bool array, True = searchable, indexed [y, x] like every grid-world array: one
(h, w) mask for every episode, or (n, h, w), one per episode. A masked cell (outside the
field's polygon, or a no-fly zone) holds no target and cannot be entered: the world treats a
move into it as off the map (docs/gridworld.md, "Masked fields"). Without a mask (None) every
function of the grid world behaves as before, bit for bit.

Distances on a mask are shortest 4-connected paths through searchable cells (around holes),
computed as BFS distance fields, vectorised over episodes: one whole-batch dilation per ring
of the wavefront, memory linear in cells (no all-pairs table).
"""

from __future__ import annotations

import numpy as np

from .actions import DELTAS

#: distance of a cell that cannot be reached (masked, or cut off from the source)
UNREACHABLE = np.iinfo(np.int32).max // 4


def episode_masks(mask: np.ndarray | None, n: int, h: int, w: int) -> np.ndarray | None:
    """A mask (h, w) or (n, h, w) checked and broadcast to a read-only (n, h, w) bool array."""
    if mask is None:
        return None
    m = np.asarray(mask)
    if m.dtype != bool:
        raise ValueError(f"a mask must be a bool array, True = searchable (got dtype {m.dtype})")
    if m.shape == (h, w):
        m = np.broadcast_to(m, (n, h, w))
    if m.shape != (n, h, w):
        raise ValueError(f"a mask must have shape ({h}, {w}) or ({n}, {h}, {w}) for this grid (got {m.shape})")
    counts = m.reshape(n, -1).sum(axis=1)
    if (counts < 2).any():
        raise ValueError(f"every mask needs at least 2 searchable cells (episode {int(np.argmin(counts))} "
                         f"has {int(counts.min())})")
    out = np.ascontiguousarray(m)
    out.flags.writeable = False
    return out


def neighbour_valid(mask: np.ndarray, pos: np.ndarray, n_actions: int = 4) -> np.ndarray:
    """(n, n_actions) bool: which moves from pos (n, 2) land on a searchable cell of the map
    (actions f, b, l, r and, with 5, the stay, always valid)."""
    n, h, w = mask.shape
    nxt = pos[:, None, :] + DELTAS[None, :n_actions]
    x, y = nxt[..., 0], nxt[..., 1]
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    rows = np.arange(n)[:, None]
    return inside & mask[rows, np.clip(y, 0, h - 1), np.clip(x, 0, w - 1)]


def blocked_view(mask: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """(n, 3, 3) bool: the view's slots (rows y - 1 .. y + 1, columns x - 1 .. x + 1) that are
    off the map or masked: the view's off-map channel on a masked field."""
    n, h, w = mask.shape
    off = np.arange(-1, 2)
    ys = pos[:, 1, None] + off
    xs = pos[:, 0, None] + off
    inside = ((ys >= 0) & (ys < h))[:, :, None] & ((xs >= 0) & (xs < w))[:, None, :]
    yc, xc = np.clip(ys, 0, h - 1), np.clip(xs, 0, w - 1)
    on = mask[np.arange(n)[:, None, None], yc[:, :, None], xc[:, None, :]]
    return ~(inside & on)


def distance_fields(mask: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """BFS distances on the mask: mask (n, h, w) bool, sources (n, 2) cells (x, y) or (n, k, 2)
    -> (n, h, w) (or (n, k, h, w)) int32 moves from the source to every cell, UNREACHABLE
    where no path through searchable cells leads. A masked source reaches nothing but itself.

    One dilation of the whole batch's wavefront per distance, so the cost is (longest distance)
    x (cells) and the memory one copy of the batch: linear in cells."""
    src = np.asarray(sources, dtype=np.int64)
    m = np.asarray(mask, dtype=bool)
    if src.ndim == 3:  # k sources per episode: k fields per episode, as one batch
        n, k = src.shape[:2]
        rep = np.repeat(m, k, axis=0)
        return distance_fields(rep, src.reshape(n * k, 2)).reshape((n, k) + m.shape[1:])
    n, h, w = m.shape
    dist = np.full((n, h, w), UNREACHABLE, np.int32)
    rows = np.arange(n)
    dist[rows, src[:, 1], src[:, 0]] = 0
    reached = np.zeros((n, h, w), bool)
    reached[rows, src[:, 1], src[:, 0]] = True
    front = reached.copy()
    grow = np.empty_like(front)
    d = 0
    while True:
        grow[:] = False
        grow[:, 1:, :] |= front[:, :-1, :]
        grow[:, :-1, :] |= front[:, 1:, :]
        grow[:, :, 1:] |= front[:, :, :-1]
        grow[:, :, :-1] |= front[:, :, 1:]
        grow &= m
        grow &= ~reached
        if not grow.any():
            return dist
        d += 1
        dist[grow] = d
        reached |= grow
        front, grow = grow, front


def step_along(dist_to_goal: np.ndarray, pos: np.ndarray, valid: np.ndarray,
               rng: np.random.Generator, prefer: np.ndarray | None = None) -> np.ndarray:
    """A move on a shortest path towards the goal whose distance field (n, h, w) is given:
    among the valid moves (n, >= 4) that reduce the distance, the one with the largest
    `prefer` (n, 4) score, ties at random; -1 where none does (at the goal, or cut off)."""
    n, h, w = dist_to_goal.shape
    nxt = pos[:, None, :] + DELTAS[None, :4]
    cx, cy = np.clip(nxt[..., 0], 0, w - 1), np.clip(nxt[..., 1], 0, h - 1)
    rows = np.arange(n)
    d0 = dist_to_goal[rows, pos[:, 1], pos[:, 0]]
    d1 = dist_to_goal[rows[:, None], cy, cx]
    closer = (d1 < d0[:, None]) & valid[:, :4]
    key = rng.random((n, 4)) * 1e-6
    if prefer is not None:
        key = key + prefer
    key = np.where(closer, key, -np.inf)
    return np.where(closer.any(axis=1), key.argmax(axis=1), -1).astype(np.int64)


def largest_component(mask: np.ndarray) -> np.ndarray:
    """(h, w) bool: the largest 4-connected part of a mask's searchable cells (the cells a drone
    that never crosses a masked cell can reach from one another). Ties: the first in row order."""
    m = np.asarray(mask, bool)
    left = m.copy()
    best = np.zeros_like(m)
    while left.any():
        ys, xs = np.nonzero(left)
        d = distance_fields(m[None], np.array([[xs[0], ys[0]]]))[0]
        part = d < UNREACHABLE
        if part.sum() > best.sum():
            best = part
        left &= ~part
    return best
