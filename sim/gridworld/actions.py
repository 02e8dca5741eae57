"""The one action enum shared by every part of the stack.

Top-left origin: f = -y, b = +y, l = -x, r = +x, n = stay (moving targets only), u = climb
one altitude level, d = descend one (only where GridConfig.levels > 1; docs/altitude.md).
The integer values are the network's class indices, so they never change: climb and descend
came later and took 5 and 6.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Action(IntEnum):
    F = 0  # forward, -y
    B = 1  # backward, +y
    L = 2  # left, -x
    R = 3  # right, +x
    N = 4  # stay
    CLIMB = 5  # one level up (levels > 1)
    DESCEND = 6  # one level down (levels > 1)


#: (dx, dy) per action, indexable by an int array of actions.
DELTAS = np.array([[0, -1], [0, 1], [-1, 0], [1, 0], [0, 0], [0, 0], [0, 0]], dtype=np.int64)
#: level change per action (climb +1, descend -1, every other action 0)
LEVEL_DELTAS = np.array([0, 0, 0, 0, 0, 1, -1], dtype=np.int64)
#: Actions available with static targets (the paper's A) and moving ones (A_ext).
STATIC_ACTIONS = 4
MOVING_ACTIONS = 5
#: with altitude levels (GridConfig.levels > 1): every action, stay included (valid_actions
#: marks stay invalid for static targets, as the paper's A has none)
LEVEL_ACTIONS = 7
#: The opposite of each action (n is its own opposite).
OPPOSITE = np.array([Action.B, Action.F, Action.R, Action.L, Action.N, Action.DESCEND, Action.CLIMB],
                    dtype=np.int64)
NAMES = "fblrnud"


def valid_mask(pos: np.ndarray, w: int, h: int, n_actions: int = STATIC_ACTIONS) -> np.ndarray:
    """Which actions keep each agent on the map. pos: (..., 2) -> (..., n_actions) bool."""
    pos = np.asarray(pos)
    nxt = pos[..., None, :] + DELTAS[:n_actions]
    return (nxt[..., 0] >= 0) & (nxt[..., 0] < w) & (nxt[..., 1] >= 0) & (nxt[..., 1] < h)
