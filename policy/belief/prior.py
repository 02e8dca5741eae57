"""The placement prior: where targets tend to start, as an (h, w) density.

Given (a GridConfig's own model, sampled) or estimated from data: from episodes (their
targets at t = 0) or from a synthesised dataset of (I, M, a) samples, where every sample whose
view shows a target in the agent's own cell marks a target's cell (solver trajectories
visit every target, so over a dataset these are the placements; for moving targets, where
they were caught). Counts are smoothed by a pseudo-count per cell so that no cell is ruled
out by a finite sample.
"""

from __future__ import annotations

import dataclasses
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
    ep = sample_episodes(_placement_only(cfg), samples, seed)
    return _histogram(ep.targets, cfg, pseudo=1e-3)


def model_pair(cfg: GridConfig, samples: int = 20_000, seed: int = 0x9E11) -> np.ndarray:
    """The config's own pair correlation, by sampling it."""
    return estimate_pair(sample_episodes(_placement_only(cfg), samples, seed), cfg)


def _placement_only(cfg: GridConfig) -> GridConfig:
    """The same placement without motion: drawing 20k moving targets' futures is slow."""
    return dataclasses.replace(cfg, motion="static", map_variant="spatial")


def estimate_pair(data: Any, cfg: GridConfig, pseudo: float = 1.0) -> np.ndarray:
    """(2h - 1, 2w - 1) pair correlation g(dy, dx): how many more target pairs sit at that
    offset than independent draws from the marginal would put there, (H + a) / (E + a), with
    H the counted ordered pairs, E their expectation under independence and a = pseudo.
    data: Episodes, (n, R, 2) target cells (one row per episode) or a dataset path (its
    episodes in which every target was met). ~1 everywhere for the
    random and gaussian placements, peaked on the lattice's offsets for the equidistant one."""
    if isinstance(data, str | Path):
        data = dataset_targets(Path(data), cfg)
    cells = np.asarray(data.targets if isinstance(data, Episodes) else data, dtype=np.int64)
    if cells.ndim != 3 or cells.shape[-1] != 2 or cells.shape[1] < 2:
        raise ValueError(f"need (episodes, R >= 2, 2) target cells (got shape {cells.shape})")
    h, w = cfg.height, cfg.width
    n, r = cells.shape[:2]
    d = cells[:, :, None, :] - cells[:, None, :, :]  # (n, R, R, 2)
    off = ~np.eye(r, dtype=bool)
    dx, dy = d[:, off, 0].ravel(), d[:, off, 1].ravel()
    hist = np.zeros((2 * h - 1, 2 * w - 1))
    np.add.at(hist, (dy + h - 1, dx + w - 1), 1.0)
    p = _histogram(cells, cfg, pseudo=0.0)
    # autocorrelation of the marginal: B(dy, dx) = sum_c p(c) p(c + d)
    pad = np.zeros((3 * h - 2, 3 * w - 2))
    pad[h - 1 : 2 * h - 1, w - 1 : 2 * w - 1] = p
    auto = np.array([[np.sum(p * pad[h - 1 + oy : 2 * h - 1 + oy, w - 1 + ox : 2 * w - 1 + ox])
                      for ox in range(-(w - 1), w)] for oy in range(-(h - 1), h)])
    expect = auto * n * r * (r - 1)
    return (hist + pseudo) / (expect + pseudo)


def dataset_targets(path: Path, cfg: GridConfig) -> np.ndarray:
    """(m, R, 2) target cells of the dataset's episodes in which all R were met (static)."""
    cells, episode = _dataset_cells(path, cfg, with_episode=True)
    r = cfg.n_targets
    order = np.argsort(episode, kind="stable")
    cells, episode = cells[order], episode[order]
    ids, start, counts = np.unique(episode, return_index=True, return_counts=True)
    full = start[counts == r]
    if len(full) == 0:
        return np.zeros((0, r, 2), np.int64)
    return cells[full[:, None] + np.arange(r)[None]]


def _dataset_cells(path: Path, cfg: GridConfig, with_episode: bool = False):
    from ..data import open_dataset

    ds = open_dataset(path)
    dcfg = ds.meta["config"]
    if (dcfg.get("width"), dcfg.get("height")) != (cfg.width, cfg.height):
        raise ValueError(
            f"{path}: dataset grid {dcfg.get('width')} x {dcfg.get('height')} differs from "
            f"{cfg.width} x {cfg.height}"
        )
    cells, episodes = [], []
    for i in range(len(ds.meta["shards"])):
        s = ds.shard(i)
        hit = s["views"][:, 0, 1, 1] > 0  # a target in the agent's own cell
        maps = s["maps"][hit, 0].reshape(int(hit.sum()), -1)
        idx = maps.argmax(axis=1)  # the agent's cell holds the map's largest value
        cells.append(np.stack([idx % cfg.width, idx // cfg.width], axis=1))
        episodes.append(s["episode"][hit])
    out = np.concatenate(cells) if cells else np.zeros((0, 2), np.int64)
    if with_episode:
        return out, (np.concatenate(episodes) if episodes else np.zeros(0, np.int64))
    return out


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
