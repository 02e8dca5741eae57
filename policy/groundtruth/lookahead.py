"""Lookahead PT for moving targets: the optimal interception order, exactly.

Targets' futures are pre-drawn (`Episodes.paths`). From (cell, time) the earliest
interception of target k is the first t' with |P_k(t') - cell|_1 <= t' - time: walk there
and wait. Targets move at most one cell per 3 steps and the agent one per step, so once it
has met a target it can shadow it: meeting earlier dominates meeting later. That makes a DP
over (visited set, last target) storing the earliest time exact, like Held-Karp, in place of
the paper's enumeration of every order.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .pt import backtrack, in_chunks

#: metric(episode (m,), a (m, 2), b (m, 2)) -> (m,) path lengths between cells
Metric = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def intercept(
    paths: np.ndarray,
    k: np.ndarray,
    cell: np.ndarray,
    time: np.ndarray,
    episode: np.ndarray | None = None,
    metric: Metric | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Earliest interception of target k[i] of episode episode[i] (default i) from
    (cell[i], time[i]); paths (n, T, R, 2). Returns (times, cells); time T - 1 if never.

    The gap f(t') = |P_k(t') - cell|_1 - (t' - time) shrinks by at most 2 per step (agent
    and target each move at most one cell), so no t' < t + ceil(f(t) / 2) can close it:
    jumping by that much is exact, needs no search window and takes a few iterations.
    metric(episode, a, b): path lengths between cells a, b (m, 2) of those episodes instead of
    Manhattan (masked fields: around the holes; the argument holds for any path metric in
    which agent and target move at most 1 per step).
    """
    big_t = paths.shape[1]
    e = np.arange(len(k)) if episode is None else np.asarray(episode)
    k = np.asarray(k)
    t = np.minimum(np.asarray(time, dtype=np.int64), big_t - 1)
    todo = np.arange(len(k))
    while len(todo):
        tt = t[todo]
        at = paths[e[todo], tt, k[todo]]
        near = np.abs(at - cell[todo]).sum(-1) if metric is None else metric(e[todo], at, cell[todo])
        gap = near - (tt - time[todo])
        more = (gap > 0) & (tt < big_t - 1)
        todo = todo[more]
        t[todo] = np.minimum(tt[more] + (gap[more] + 1) // 2, big_t - 1)
    return t, paths[e, t, k]


def lookahead_dp(
    start: np.ndarray, paths: np.ndarray, rng: np.random.Generator | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """start (n, 2), paths (n, T, R, 2) -> (lengths (n,), orders (n, R)). Ties at random.

    One vectorised step per subset: every (last target j, previous target i) pair of the
    subset is intercepted at once over all episodes.
    """
    return in_chunks(_lookahead_dp, start, paths, paths.shape[2], rng)


def _lookahead_dp(
    start: np.ndarray, paths: np.ndarray, rng: np.random.Generator | None, metric: Metric | None = None
) -> tuple[np.ndarray, np.ndarray]:
    n, _, r = paths.shape[:3]
    rows = np.arange(n)
    full = (1 << r) - 1
    big = np.iinfo(np.int64).max // 4
    dp = np.full((n, 1 << r, r), big, dtype=np.int64)
    parent = np.full((n, 1 << r, r), -1, dtype=np.int8)
    noise = rng.random((n, 1 << r, r)) * 0.5 if rng is not None else np.zeros((n, 1 << r, r))
    for j in range(r):
        dp[:, 1 << j, j], _ = intercept(paths, np.full(n, j), start, np.zeros(n, dtype=np.int64), metric=metric)
    for mask in range(1, full + 1):
        members = [i for i in range(r) if mask >> i & 1]
        m = len(members)
        if m < 2:
            continue
        # pairs (j last, i before it), grouped by j: (m, m - 1)
        js = np.repeat(members, m - 1)
        iss = np.array([i for j in members for i in members if i != j])
        prevs = mask ^ (1 << js)
        t0 = dp[:, prevs, iss]  # (n, P)
        cells = paths[rows[:, None], t0, iss[None]]  # (n, P, 2)
        p = len(js)
        t, _ = intercept(
            paths, np.tile(js, n), cells.reshape(-1, 2), t0.reshape(-1), np.repeat(rows, p), metric
        )
        t = t.reshape(n, m, m - 1)
        key = (t + noise[:, prevs, iss].reshape(n, m, m - 1)).argmin(axis=2)  # (n, m)
        dp[:, mask, members] = np.take_along_axis(t, key[..., None], axis=2)[..., 0]
        parent[:, mask, members] = iss.reshape(m, m - 1)[np.arange(m)[None], key]
    cur = (dp[:, full, :] + noise[:, full, :]).argmin(axis=1)
    return dp[rows, full, cur], backtrack(parent, cur)
