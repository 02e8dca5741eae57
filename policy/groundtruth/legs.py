"""Turning a goal cell into a move: the paper's Eq. 3, vectorised.

Eq. 3 splits the angle to the goal into pi/2-wide sectors around the axes, so the move is
along the axis with the larger remaining offset, and a random one of the two on an exact
diagonal. Every such walk is a shortest (Manhattan) path.
"""

from __future__ import annotations

import numpy as np

from sim.gridworld import Action


def step_towards(pos: np.ndarray, goal: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """pos, goal (n, 2) -> (n,) actions; Action.N where pos == goal."""
    d = goal - pos
    ax, ay = np.abs(d[:, 0]), np.abs(d[:, 1])
    horiz = np.where(d[:, 0] > 0, Action.R, Action.L)
    vert = np.where(d[:, 1] > 0, Action.B, Action.F)
    coin = rng.random(len(pos)) < 0.5
    out = np.where(ax > ay, horiz, np.where(ay > ax, vert, np.where(coin, horiz, vert)))
    return np.where((ax == 0) & (ay == 0), Action.N, out).astype(np.int64)


def manhattan(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(a - b).sum(axis=-1)
