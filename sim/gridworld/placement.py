"""Target placement models P (paper Section VI-D), vectorised over episodes.

The agent is placed first, uniformly over all cells; targets never start on the agent or on
each other (the authors' code; targets may share a row or column, Eq. 1 read loosely).
"""

from __future__ import annotations

import numpy as np

from .config import GridConfig


def lattice_offsets(cfg: GridConfig) -> np.ndarray:
    """(R, 2) offsets of the fixed-shape lattice: row-major, `grid_spacing` apart."""
    cols, _ = cfg.lattice_shape
    i = np.arange(cfg.n_targets)
    return np.stack([i % cols, i // cols], axis=1) * cfg.grid_spacing


def fixed_layout(cfg: GridConfig) -> np.ndarray:
    """The one layout used by every 'fixed' episode: the lattice centred on the map."""
    off = lattice_offsets(cfg)
    span = off.max(axis=0)
    origin = (np.array([cfg.width, cfg.height]) - 1 - span) // 2
    return off + origin


def place_agents(cfg: GridConfig, rng: np.random.Generator, n: int) -> np.ndarray:
    cells = rng.integers(0, cfg.width * cfg.height, size=n)
    return np.stack([cells % cfg.width, cells // cfg.width], axis=1).astype(np.int64)


def _random(cfg: GridConfig, rng: np.random.Generator, agent: np.ndarray) -> np.ndarray:
    n, wh = len(agent), cfg.width * cfg.height
    keys = rng.random((n, wh))
    keys[np.arange(n), agent[:, 1] * cfg.width + agent[:, 0]] = np.inf
    cells = np.argsort(keys, axis=1)[:, : cfg.n_targets]
    return np.stack([cells % cfg.width, cells // cfg.width], axis=-1).astype(np.int64)


def _gaussian(cfg: GridConfig, rng: np.random.Generator, agent: np.ndarray) -> np.ndarray:
    n = len(agent)
    out = np.full((n, cfg.n_targets, 2), -1, dtype=np.int64)
    mean = np.asarray(cfg.gaussian_mean, dtype=np.float64)
    for k in range(cfg.n_targets):
        todo = np.arange(n)
        for _ in range(10_000):
            if todo.size == 0:
                break
            c = np.rint(rng.normal(mean, cfg.gaussian_sd, size=(todo.size, 2))).astype(np.int64)
            ok = (c[:, 0] >= 0) & (c[:, 0] < cfg.width) & (c[:, 1] >= 0) & (c[:, 1] < cfg.height)
            ok &= ~np.all(c == agent[todo], axis=1)
            if k:
                ok &= ~np.any(np.all(out[todo, :k] == c[:, None], axis=2), axis=1)
            out[todo[ok], k] = c[ok]
            todo = todo[~ok]
        else:  # pragma: no cover - only with absurd parameters
            raise RuntimeError("gaussian placement did not converge; widen gaussian_sd")
    return out


def _equidistant(cfg: GridConfig, rng: np.random.Generator, agent: np.ndarray) -> np.ndarray:
    off = lattice_offsets(cfg)
    span = off.max(axis=0)
    ox = np.arange(cfg.width - span[0])
    oy = np.arange(cfg.height - span[1])
    origins = np.stack(np.meshgrid(ox, oy, indexing="xy"), axis=-1).reshape(-1, 2)  # (O, 2)
    layouts = origins[:, None, :] + off[None]  # (O, R, 2)
    # An origin is allowed for an episode when no target of it lands on that episode's agent.
    hits = np.any(np.all(layouts[None] == agent[:, None, None, :], axis=-1), axis=-1)  # (n, O)
    keys = rng.random(hits.shape)
    keys[hits] = np.inf
    return layouts[np.argmin(keys, axis=1)]


def _fixed(cfg: GridConfig, rng: np.random.Generator, agent: np.ndarray) -> np.ndarray:
    return np.broadcast_to(fixed_layout(cfg), (len(agent), cfg.n_targets, 2)).copy()


def place(cfg: GridConfig, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n episodes -> agent (n, 2) and targets (n, R, 2), cells as (x, y)."""
    agent = place_agents(cfg, rng, n)
    if cfg.distribution == "fixed":
        # The agent is uniform over the cells the fixed layout leaves free.
        layout = fixed_layout(cfg)
        free = np.ones((cfg.height, cfg.width), bool)
        free[layout[:, 1], layout[:, 0]] = False
        fy, fx = np.nonzero(free)
        pick = rng.integers(0, fx.size, size=n)
        agent = np.stack([fx[pick], fy[pick]], axis=1).astype(np.int64)
    fn = {"random": _random, "gaussian": _gaussian, "equidistant": _equidistant, "fixed": _fixed}
    return agent, fn[cfg.distribution](cfg, rng, agent)
