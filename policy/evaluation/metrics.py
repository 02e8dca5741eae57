"""Table I's columns as pure functions of per-episode arrays. Definitions: docs/metrics.md."""

from __future__ import annotations

import numpy as np


def recovery_rate(find_moves: np.ndarray) -> np.ndarray:
    """Column (g) per episode: the mean over found targets of 1 / (moves since the previous
    find, or since the start); 0 when nothing was found. find_moves (n, R), -1 = not found."""
    f = np.where(find_moves < 0, np.iinfo(np.int64).max, find_moves).astype(np.int64)
    f = np.sort(f, axis=1)
    found = f < np.iinfo(np.int64).max
    prev = np.concatenate([np.zeros((len(f), 1), dtype=np.int64), f[:, :-1]], axis=1)
    gaps = np.where(found, f - prev, 1)
    # simultaneous finds (two targets met in one move) share the gap of that move
    gaps = np.maximum(gaps, 1)
    recip = np.where(found, 1.0 / gaps, 0.0)
    n_found = found.sum(axis=1)
    return np.where(n_found > 0, recip.sum(axis=1) / np.maximum(n_found, 1), 0.0)


def table1_columns(
    moves: np.ndarray,
    optimal: np.ndarray,
    find_moves: np.ndarray,
    loops: np.ndarray | None,
    t_e: int = 300,
) -> dict[str, float | None]:
    """Every Table I column (a)-(g) plus the plain numbers a user reads at once."""
    moves = np.asarray(moves, dtype=np.int64)
    optimal = np.asarray(optimal, dtype=np.int64)
    find_moves = np.asarray(find_moves, dtype=np.int64)
    if moves.shape != optimal.shape or moves.ndim != 1 or len(moves) == 0:
        raise ValueError("moves and optimal must be equal-length 1-D arrays with >= 1 episode")
    if find_moves.ndim != 2 or len(find_moves) != len(moves):
        raise ValueError(f"find_moves must be (episodes, targets); got {find_moves.shape} for {len(moves)} episodes")
    if loops is not None:
        loops = np.asarray(loops, dtype=np.int64)
        if loops.shape != moves.shape:
            raise ValueError(f"loops must be one count per episode; got {loops.shape} for {len(moves)} episodes")
    if (optimal < 1).any():
        raise ValueError("optimal lengths must be >= 1 (the agent never starts on a target)")
    n = len(moves)
    pct = lambda x: float(100.0 * np.count_nonzero(x) / n)  # noqa: E731
    diff = moves - optimal
    rr = recovery_rate(find_moves)
    found = (find_moves >= 0).sum(axis=1)
    out: dict[str, float | None] = {
        "episodes": n,
        "loop_pct": None,
        "multi_loop_pct": None,
        "over_100_pct": pct(moves > 100),
        "optimal_pct": pct(moves == optimal),
        "diff_lt_10_pct": pct(diff < 10),
        "diff_le_10_pct": pct(diff <= 10),
        "timeout_pct": pct(moves > t_e),
        "recovery_rate_mean": float(rr.mean()),
        "recovery_rate_sd": float(rr.std()),
        "mean_moves": float(moves.mean()),
        "sd_moves": float(moves.std()),
        "mean_optimal_moves": float(optimal.mean()),
        "mean_ratio_to_optimal": float((moves / optimal).mean()),
        "success_pct": pct(found == find_moves.shape[1]),
        "targets_per_move": float(found.sum() / moves.sum()),
    }
    if loops is not None:
        # (b) over the looping episodes only; 0 (not undefined) when none looped
        looped = loops > 0
        out["loop_pct"] = pct(looped)
        out["multi_loop_pct"] = (
            float(100.0 * np.count_nonzero(loops > 1) / np.count_nonzero(looped)) if looped.any() else 0.0
        )
    return out
