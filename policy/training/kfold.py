"""The k-fold split and where each fold's files live.

A fold's files: `fold{k}.partial.pt` after every epoch (weights, optimiser and RNG state, the
rows so far) and `fold{k}.pt` once it is done. A resumed run continues every fold from what it
finds, so folds that trained in parallel processes resume the same way as sequential ones.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def kfold_split(n: int, k: int, seed: int) -> list[np.ndarray]:
    """k disjoint index sets covering range(n), after one seeded shuffle (sizes differ by <= 1)."""
    if not 2 <= k <= n:
        raise ValueError(f"k-fold needs 2 <= k <= samples (k={k}, samples={n})")
    order = np.random.default_rng([seed, 0xF01D]).permutation(n)
    return np.array_split(order, k)


def train_indices(folds: list[np.ndarray], fold: int) -> np.ndarray:
    return np.concatenate([f for i, f in enumerate(folds) if i != fold])


def partial_path(out: Path, fold: int) -> Path:
    return Path(out) / f"fold{fold}.partial.pt"


def final_path(out: Path, fold: int) -> Path:
    return Path(out) / f"fold{fold}.pt"
