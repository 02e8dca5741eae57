"""Lookahead PT for moving targets: the optimal interception order, exactly.

Targets' futures are pre-drawn (`Episodes.paths`). From (cell, time) the earliest
interception of target k is the first t' with |P_k(t') - cell|_1 <= t' - time: walk there
and wait. Targets move at most one cell per 3 steps and the agent one per step, so once it
has met a target it can shadow it: meeting earlier dominates meeting later. That makes a DP
over (visited set, last target) storing the earliest time exact, like Held-Karp, in place of
the paper's enumeration of every order.
"""

from __future__ import annotations

import numpy as np

from .pt import backtrack

#: how far ahead an interception is searched; a 10 x 10 target fleeing at 1/3 speed is
#: always caught within ~27 steps, so 64 leaves room for larger grids and slower agents.
WINDOW = 64


def intercept(
    paths: np.ndarray, k: np.ndarray, cell: np.ndarray, time: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Earliest interception of target k[i] in episode i from (cell[i], time[i]).

    paths (n, T, R, 2); returns (times (n,), cells (n, 2)); time T - 1 when none in range.
    """
    n, big_t = paths.shape[:2]
    rows = np.arange(n)
    ts = np.minimum(time[:, None] + np.arange(WINDOW)[None], big_t - 1)  # (n, W)
    pos = paths[rows[:, None], ts, k[:, None]]  # (n, W, 2)
    reach = np.abs(pos - cell[:, None, :]).sum(-1) <= ts - time[:, None]
    first = reach.argmax(axis=1)
    ok = reach[rows, first]
    t_hit = np.where(ok, ts[rows, first], big_t - 1)
    return t_hit, paths[rows, t_hit, k]


def lookahead_dp(
    start: np.ndarray, paths: np.ndarray, rng: np.random.Generator | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """start (n, 2), paths (n, T, R, 2) -> (lengths (n,), orders (n, R)). Ties at random."""
    n, _, r = paths.shape[:3]
    rows = np.arange(n)
    full = (1 << r) - 1
    big = np.iinfo(np.int64).max // 4
    dp = np.full((n, 1 << r, r), big, dtype=np.int64)
    parent = np.full((n, 1 << r, r), -1, dtype=np.int8)
    noise = rng.random((n, 1 << r, r)) * 0.5 if rng is not None else np.zeros((n, 1 << r, r))
    zero = np.zeros(n, dtype=np.int64)
    for j in range(r):
        t, _ = intercept(paths, np.full(n, j), start, zero)
        dp[:, 1 << j, j] = t
    for mask in range(1, full + 1):
        members = [i for i in range(r) if mask >> i & 1]
        if len(members) < 2:
            continue
        for j in members:
            prev = mask ^ (1 << j)
            best = np.full(n, big, dtype=np.int64)
            best_key = np.full(n, np.inf)
            arg = np.full(n, -1, dtype=np.int64)
            for i in (i for i in range(r) if prev >> i & 1):
                t0 = dp[:, prev, i]
                cell = paths[rows, np.minimum(t0, paths.shape[1] - 1), i]
                t, _ = intercept(paths, np.full(n, j), cell, t0)
                key = t + noise[:, prev, i]
                better = key < best_key
                best_key = np.where(better, key, best_key)
                best = np.where(better, t, best)
                arg = np.where(better, i, arg)
            dp[:, mask, j] = best
            parent[:, mask, j] = arg
    key = dp[:, full, :] + noise[:, full, :]
    cur = key.argmin(axis=1)
    return dp[rows, full, cur], backtrack(parent, cur)
