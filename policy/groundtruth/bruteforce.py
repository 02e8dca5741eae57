"""Reference solvers by exhaustive enumeration of target orders (the paper's PT): slow,
obviously right, used by the tests and the benchmark to check the fast solvers."""

from __future__ import annotations

from itertools import permutations

import numpy as np


def pt_bruteforce(start: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """start (n, 2), targets (n, R, 2) -> optimal lengths (n,), by trying all R! orders."""
    r = targets.shape[1]
    perms = np.array(list(permutations(range(r))))  # (P, R)
    best = np.full(len(start), np.iinfo(np.int64).max)
    for i, (s, t) in enumerate(zip(start, targets, strict=True)):
        seq = t[perms]  # (P, R, 2)
        pts = np.concatenate([np.broadcast_to(s, (len(perms), 1, 2)), seq], axis=1)
        best[i] = np.abs(np.diff(pts, axis=1)).sum(axis=(1, 2)).min()
    return best


def intercept_scan(
    paths: np.ndarray, k: np.ndarray, cell: np.ndarray, time: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Earliest interception by checking every future time of the whole horizon."""
    n, big_t = paths.shape[:2]
    rows = np.arange(n)
    ts = np.arange(big_t)
    pos = paths[rows[:, None], ts[None], k[:, None]]  # (n, T, 2)
    reach = (np.abs(pos - cell[:, None]).sum(-1) <= ts - time[:, None]) & (ts >= time[:, None])
    t = np.where(reach.any(1), reach.argmax(1), big_t - 1)
    return t, paths[rows, t, k]


def lookahead_bruteforce(start: np.ndarray, paths: np.ndarray) -> np.ndarray:
    """Earliest completion over all R! orders, leg by leg with earliest interception."""
    n, _, r = paths.shape[:3]
    best = np.full(n, np.iinfo(np.int64).max)
    for order in permutations(range(r)):
        t = np.zeros(n, dtype=np.int64)
        cell = start.copy()
        for k in order:
            t, cell = intercept_scan(paths, np.full(n, k), cell, t)
        best = np.minimum(best, t)
    return best
