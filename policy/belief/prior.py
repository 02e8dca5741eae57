"""The placement prior: where targets tend to start, as an (h, w) density.

Given (a GridConfig's own model, sampled) or estimated from data: from episodes (their
targets at t = 0) or from a synthesised dataset of (I, M, a) samples, where every sample whose
view shows a target in the agent's own cell marks a target's cell (solver trajectories
visit every target, so over a dataset these are the placements; for moving targets, where
they were caught). Counts are smoothed by a pseudo-count per cell so that no cell is ruled
out by a finite sample.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sim.gridworld import Episodes, GridConfig, sample_episodes


def _histogram(cells: np.ndarray, cfg: GridConfig, pseudo: float) -> np.ndarray:
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    ok = (cells[:, 0] >= 0) & (cells[:, 0] < cfg.width) & (cells[:, 1] >= 0) & (cells[:, 1] < cfg.height)
    counts = np.zeros((cfg.height, cfg.width))
    np.add.at(counts, (cells[ok, 1], cells[ok, 0]), 1.0)
    counts += pseudo
    return counts / counts.sum()


def model_prior(cfg: GridConfig, samples: int = 20_000, seed: int = 0x9E10) -> np.ndarray:
    """The config's own placement model, by sampling it (the prior 'given')."""
    ep = sample_episodes(cfg, samples, seed)
    return _histogram(ep.targets, cfg, pseudo=1e-3)


def _dataset_cells(path: Path, cfg: GridConfig) -> np.ndarray:
    from ..data import open_dataset

    ds = open_dataset(path)
    dcfg = ds.meta["config"]
    if (dcfg.get("width"), dcfg.get("height")) != (cfg.width, cfg.height):
        raise ValueError(
            f"{path}: dataset grid {dcfg.get('width')} x {dcfg.get('height')} differs from "
            f"{cfg.width} x {cfg.height}"
        )
    cells = []
    for i in range(len(ds.meta["shards"])):
        s = ds.shard(i)
        hit = s["views"][:, 0, 1, 1] > 0  # a target in the agent's own cell
        maps = s["maps"][hit, 0].reshape(int(hit.sum()), -1)
        idx = maps.argmax(axis=1)  # the agent's cell holds the map's largest value
        cells.append(np.stack([idx % cfg.width, idx // cfg.width], axis=1))
    return np.concatenate(cells) if cells else np.zeros((0, 2), np.int64)


def estimate_prior(data: Any, cfg: GridConfig, pseudo: float = 0.5) -> np.ndarray:
    """(h, w) placement density (sums to 1) from data: Episodes, an (n, R, 2) array of target
    cells, or the path of a synthesised dataset. pseudo: smoothing counts per cell."""
    if pseudo < 0:
        raise ValueError(f"pseudo must be >= 0 (got {pseudo})")
    if isinstance(data, Episodes):
        cells = data.targets
    elif isinstance(data, str | Path):
        path = Path(data)
        if not path.exists():
            raise FileNotFoundError(f"no dataset at {path}")
        cells = _dataset_cells(path, cfg)
    else:
        cells = np.asarray(data)
        if cells.ndim < 2 or cells.shape[-1] != 2:
            raise ValueError(f"target cells must be (..., 2) (got shape {cells.shape})")
    if len(cells) == 0 and pseudo == 0:
        raise ValueError("no target cells in the data and no smoothing: the prior is undefined")
    return _histogram(cells, cfg, pseudo)
