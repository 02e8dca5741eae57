"""The agent's two inputs (paper Fig. 1): the 3 x 3 view I and the visitation map M.

View I: (3, 3, 3) uint8 in {0, 1}, channels (target, off-map, agent), rows = y - 1 .. y + 1,
columns = x - 1 .. x + 1. The authors drew off-map cells like empty ones; we encode them
distinctly (a deliberate improvement, see docs/gridworld.md). Targets show whether found or not.

Map M: (C, h, w) float32, row = y. spatial: visited 1, agent 10. memory (+M): cells where a
target was met 5 (the agent's 10 wins). spatiotemporal: channel 0 trail (current cell 50,
decays 1 per step), channel 1 recoveries (each meeting cell 50, decays the same way).
"""

from __future__ import annotations

import numpy as np

VIEW_CHANNELS = 3
#: with altitude levels: (detection, off-map, agent, outside the level's footprint), W x W
#: slots, W = 2 * levels + 1 (sim.gridworld.batch.BatchGridWorld._sampled_views)
LEVEL_VIEW_CHANNELS = 4
AGENT_VALUE, VISITED_VALUE, MET_VALUE = 10.0, 1.0, 5.0
_OFF = np.arange(-1, 2)


def target_occupancy(targets: np.ndarray, w: int, h: int) -> np.ndarray:
    """(n, R, 2) cells -> (n, h, w) bool."""
    n = targets.shape[0]
    occ = np.zeros((n, h, w), dtype=bool)
    occ[np.arange(n)[:, None], targets[..., 1], targets[..., 0]] = True
    return occ


def views(agent: np.ndarray, occupancy: np.ndarray) -> np.ndarray:
    """agent (n, 2), occupancy (n, h, w) bool -> (n, 3, 3, 3) uint8 views."""
    n, h, w = occupancy.shape
    ys = agent[:, 1, None] + _OFF  # (n, 3)
    xs = agent[:, 0, None] + _OFF
    inside = ((ys >= 0) & (ys < h))[:, :, None] & ((xs >= 0) & (xs < w))[:, None, :]
    yc, xc = np.clip(ys, 0, h - 1), np.clip(xs, 0, w - 1)
    tgt = occupancy[np.arange(n)[:, None, None], yc[:, :, None], xc[:, None, :]] & inside
    out = np.zeros((n, VIEW_CHANNELS, 3, 3), dtype=np.uint8)
    out[:, 0] = tgt
    out[:, 1] = ~inside
    out[:, 2, 1, 1] = 1
    return out


def spatial_map(agent: np.ndarray, visited: np.ndarray, met: np.ndarray | None = None) -> np.ndarray:
    """visited (n, h, w) bool [, met (n, h, w) bool] -> (n, 1, h, w) float32."""
    m = visited.astype(np.float32) * VISITED_VALUE
    if met is not None:
        m[met] = MET_VALUE
    m[np.arange(len(agent)), agent[:, 1], agent[:, 0]] = AGENT_VALUE
    return m[:, None]
