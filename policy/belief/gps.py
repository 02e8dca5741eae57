"""Position uncertainty maths shared by the grid-world evaluation and the flight: how much of a
Gaussian position posterior falls in each grid cell, and the expected (probabilistic) map.

Cells are squares of side 1 (grid units) centred on their grid point; the axis-aligned case
integrates exactly with the normal CDF, per axis, batched over episodes. Mass beyond the field
is folded back onto it (the vehicle is known to be over the field)."""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from sim.gridworld.observations import AGENT_VALUE, VISITED_VALUE


def cell_probabilities_xy(mean_xy: np.ndarray, sd_cells: np.ndarray | float, width: int,
                          height: int, fold: bool = True) -> np.ndarray:
    """(n, 2) means (x, y) in fractional cells, sd in cells: scalar, (n,) (both axes) or
    (n, 2) (per axis) -> (n, h, w) probability of the position being in each cell.
    fold: renormalise over the field."""
    mean_xy = np.atleast_2d(np.asarray(mean_xy, dtype=np.float64))
    n = len(mean_xy)
    sd = np.asarray(sd_cells, dtype=np.float64)
    sd = np.broadcast_to(sd[..., None] if sd.ndim < 2 else sd, (n, 2))
    if (sd <= 0).any() or not np.all(np.isfinite(sd)):
        raise ValueError("sd_cells must be finite and > 0")
    ex = np.arange(width + 1) - 0.5
    ey = np.arange(height + 1) - 0.5
    px = np.diff(ndtr((ex[None] - mean_xy[:, 0, None]) / sd[:, 0, None]), axis=1)  # (n, w)
    py = np.diff(ndtr((ey[None] - mean_xy[:, 1, None]) / sd[:, 1, None]), axis=1)  # (n, h)
    p = py[:, :, None] * px[:, None, :]
    if fold:
        tot = p.sum(axis=(1, 2), keepdims=True)
        p = p / np.maximum(tot, 1e-300)
    return p


def expected_spatial_map(visited_prob: np.ndarray, position_prob: np.ndarray) -> np.ndarray:
    """(n, h, w) P(visited), P(here now) -> (n, 1, h, w) float32 expectation of the crisp
    spatial map (visited 1, agent 10): what a network trained on crisp maps reads."""
    m = (1.0 - position_prob) * visited_prob * VISITED_VALUE + position_prob * AGENT_VALUE
    return m[:, None].astype(np.float32)
