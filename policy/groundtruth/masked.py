"""The exact solvers on masked fields: distances are shortest paths through searchable cells
(around holes), from BFS distance fields (sim.gridworld.masks), never Manhattan.

Held-Karp stays exact: its costs are the true path lengths between the start and the
targets, and an optimal tour on those is an optimal walk on the field (a walk between
targets is a shortest path, and passing over another target on the way only finds it
earlier). The oracle follows each leg down the goal's distance field.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sim.gridworld.masks import UNREACHABLE, distance_fields, step_along

from .pt import TABLE_ENTRIES, order_dp

#: episodes per batch of distance fields: (batch, R, h, w) int32 at most ~64 MB
_FIELD_ENTRIES = 1 << 24


def masked_costs(mask: np.ndarray, start: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """mask (n, h, w), start (n, 2), targets (n, R, 2) -> (d0 (n, R), dd (n, R, R)) int64 path
    lengths on the mask (UNREACHABLE where a target is cut off)."""
    n, r = targets.shape[:2]
    fields = distance_fields(mask, targets)  # (n, R, h, w): from each target
    rows = np.arange(n)
    d0 = fields[rows[:, None], np.arange(r)[None], start[:, None, 1], start[:, None, 0]]
    dd = fields[rows[:, None, None], np.arange(r)[None, :, None], targets[:, None, :, 1], targets[:, None, :, 0]]
    return d0.astype(np.int64), dd.astype(np.int64)


def held_karp_masked(start: np.ndarray, targets: np.ndarray, mask: np.ndarray,
                     rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """held_karp on masked fields: (lengths (n,), orders (n, R)), lengths in moves."""
    n, r = targets.shape[:2]
    h, w = mask.shape[1:]
    step = max(1, min(TABLE_ENTRIES // ((1 << r) * r), _FIELD_ENTRIES // (r * h * w)))
    lengths, orders = [], []
    for i in range(0, n, step):
        s, t, m = start[i: i + step], targets[i: i + step], mask[i: i + step]
        d0, dd = masked_costs(m, s, t)
        order = order_dp(d0.astype(np.float64), dd.astype(np.float64), rng)
        rows = np.arange(len(s))
        legs = d0[rows, order[:, 0]] + dd[rows[:, None], order[:, :-1], order[:, 1:]].sum(axis=1)
        lengths.append(np.minimum(legs, UNREACHABLE))
        orders.append(order)
    return np.concatenate(lengths), np.concatenate(orders)


def move_towards(mask: np.ndarray, pos: np.ndarray, goal: np.ndarray, valid: np.ndarray,
                 rng: np.random.Generator) -> np.ndarray:
    """A move on a shortest path (on the mask) from pos to goal, ties at random; Action.N (4)
    at the goal, and a random valid move where the goal cannot be reached."""
    from ..base import random_valid

    a = step_along(distance_fields(mask, goal), pos, valid, rng)
    at = np.all(pos == goal, axis=1)
    a[at] = 4
    lost = (a < 0)
    if lost.any():
        a[lost] = random_valid(valid[lost, :4], rng)
    return a


def all_pairs(mask: np.ndarray) -> np.ndarray:
    """(m, h * w, h * w) int32 path lengths between every two cells of each episode's mask
    (row: from cell y * w + x). Quadratic in cells: for the moving-target oracle only, which
    needs the distance between any two cells at any time (the planner uses one BFS field)."""
    m, h, w = mask.shape
    cells = np.stack(np.divmod(np.arange(h * w), w)[::-1], axis=1)  # (hw, 2) as (x, y)
    return distance_fields(mask, np.broadcast_to(cells, (m, h * w, 2))).reshape(m, h * w, h * w)


def lookahead_dp_masked(start: np.ndarray, paths: np.ndarray, mask: np.ndarray,
                        rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """lookahead_dp on masked fields: earliest interceptions on path lengths around the holes
    (exact by the same argument: agent and target each move at most one cell of the field per
    step). Episodes in batches whose all-pairs tables stay under ~64 MB."""
    from .lookahead import _lookahead_dp

    n, _, r = paths.shape[:3]
    h, w = mask.shape[1:]
    step = max(1, min(TABLE_ENTRIES // ((1 << r) * r), _FIELD_ENTRIES // (h * w) ** 2))
    lengths, orders = [], []
    for i in range(0, n, step):
        table = all_pairs(mask[i: i + step])

        def metric(e: np.ndarray, a: np.ndarray, b: np.ndarray, table: np.ndarray = table) -> np.ndarray:
            return table[e, a[:, 1] * w + a[:, 0], b[:, 1] * w + b[:, 0]].astype(np.int64)

        got = _lookahead_dp(start[i: i + step], paths[i: i + step], rng, metric)
        lengths.append(got[0])
        orders.append(got[1])
    return np.concatenate(lengths), np.concatenate(orders)


def table_metric(mask: np.ndarray) -> Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """A lookahead metric over all of mask's episodes (the oracle's moves, one table)."""
    table = all_pairs(mask)
    w = mask.shape[2]

    def metric(e: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return table[e, a[:, 1] * w + a[:, 0], b[:, 1] * w + b[:, 0]].astype(np.int64)

    return metric
