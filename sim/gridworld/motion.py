"""Target motion (paper Section VI-F), pre-drawn for the whole episode so that the
lookahead solver sees the same future the episode will play out.

Targets move on transitions t -> t+1 where t % target_period == 0 (1/3 speed). Targets are
processed one after another, each into a cell no other target holds, so no two targets ever
share a cell.
"""

from __future__ import annotations

import numpy as np

from .actions import DELTAS, OPPOSITE
from .config import GridConfig

_TRIES = 8


def _in_bounds(c: np.ndarray, cfg: GridConfig, mask: np.ndarray | None = None) -> np.ndarray:
    """c (m, 2) on the map; with mask ((m, h, w) bool, the episodes' masks row by row), also
    on a searchable cell: a masked cell is off the map for a target too."""
    inside = (c[..., 0] >= 0) & (c[..., 0] < cfg.width) & (c[..., 1] >= 0) & (c[..., 1] < cfg.height)
    if mask is None:
        return inside
    rows = np.arange(len(c))
    return inside & mask[rows, np.clip(c[:, 1], 0, cfg.height - 1), np.clip(c[:, 0], 0, cfg.width - 1)]


def _free(pos: np.ndarray, k: int, cand: np.ndarray) -> np.ndarray:
    """cand (n, 2) is not held by any target other than k. pos (n, R, 2)."""
    same = np.all(pos == cand[:, None, :], axis=-1)
    same[:, k] = False
    return ~np.any(same, axis=1)


def _random_walk_step(cfg: GridConfig, rng: np.random.Generator, pos: np.ndarray,
                      mask: np.ndarray | None = None) -> np.ndarray:
    pos = pos.copy()
    n, r = pos.shape[:2]
    for k in range(r):
        todo = np.arange(n)
        for _ in range(_TRIES):
            if todo.size == 0:
                break
            a = rng.integers(0, 4, size=todo.size)
            cand = pos[todo, k] + DELTAS[a]
            ok = _in_bounds(cand, cfg, None if mask is None else mask[todo]) & _free(pos[todo], k, cand)
            pos[todo[ok], k] = cand[ok]
            todo = todo[~ok]
        # Targets boxed in after a few tries stay where they are this step.
    return pos


def _herd_step(
    cfg: GridConfig, rng: np.random.Generator, pos: np.ndarray, direction: np.ndarray,
    mask: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    pos = pos.copy()
    n, r = pos.shape[:2]
    # Deviations: one of the two perpendicular moves or stay, never along the herd's axis.
    perp = np.where(direction[:, None] < 2, np.array([2, 3, 4]), np.array([0, 1, 4]))  # (n, 3)
    border = np.zeros(n, bool)
    for k in range(r):
        deviate = rng.random(n) < cfg.herd_deviation
        a = np.where(deviate, perp[np.arange(n), rng.integers(0, 3, size=n)], direction)
        cand = pos[:, k] + DELTAS[a]
        inside = _in_bounds(cand, cfg, mask)
        border |= ~inside & ~deviate
        ok = inside & _free(pos, k, cand)
        pos[ok, k] = cand[ok]
    if border.any():
        # A new, different group direction after a target met the border.
        shift = rng.integers(1, 4, size=int(border.sum()))
        direction = direction.copy()
        direction[border] = (direction[border] + shift) % 4
    return pos, direction


def target_paths(cfg: GridConfig, rng: np.random.Generator, targets: np.ndarray,
                 mask: np.ndarray | None = None) -> np.ndarray:
    """targets (n, R, 2) at t=0 -> (n, t_e + 2, R, 2) positions for t = 0 .. t_e + 1.
    mask: (n, h, w) bool searchable cells, or None; targets never step into a masked cell
    (treated as the map's edge: a random walker redraws, a herd member stays and turns the herd)."""
    n = targets.shape[0]
    steps = cfg.t_e + 2
    out = np.empty((n, steps) + targets.shape[1:], dtype=np.int64)
    out[:, 0] = targets
    pos = targets.astype(np.int64)
    direction = rng.integers(0, 4, size=n)
    for t in range(steps - 1):
        if cfg.motion != "static" and t % cfg.target_period == 0:
            if cfg.motion == "random_walk":
                pos = _random_walk_step(cfg, rng, pos, mask)
            else:
                pos, direction = _herd_step(cfg, rng, pos, direction, mask)
        out[:, t + 1] = pos
    return out


__all__ = ["target_paths", "OPPOSITE"]
