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


def _gaussian(cfg: GridConfig, rng: np.random.Generator, agent: np.ndarray,
              mask: np.ndarray | None = None) -> np.ndarray:
    """Targets drawn round gaussian_mean, redrawn off the grid, on the agent, on another
    target or (mask: (n, h, w) searchable cells) on a masked cell."""
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
            if mask is not None:
                ok &= mask[todo, np.clip(c[:, 1], 0, cfg.height - 1), np.clip(c[:, 0], 0, cfg.width - 1)]
            ok &= ~np.all(c == agent[todo], axis=1)
            if k:
                ok &= ~np.any(np.all(out[todo, :k] == c[:, None], axis=2), axis=1)
            out[todo[ok], k] = c[ok]
            todo = todo[~ok]
        else:
            if mask is not None:
                raise ValueError("gaussian placement found no searchable cell near gaussian_mean on a mask; "
                                 "move the mean onto the field or widen gaussian_sd")
            raise RuntimeError("gaussian placement did not converge; widen gaussian_sd")  # pragma: no cover
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


def _uniform_cells(rng: np.random.Generator, free: np.ndarray) -> np.ndarray:
    """One cell (x, y) per episode, uniform over its free cells: free (n, h, w) bool."""
    n, h, w = free.shape
    keys = rng.random((n, h * w))
    keys[~free.reshape(n, -1)] = -1.0
    idx = keys.argmax(axis=1)
    return np.stack([idx % w, idx // w], axis=1).astype(np.int64)


def place_masked(cfg: GridConfig, rng: np.random.Generator, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """place() on masked fields, mask (n, h, w) bool searchable: the agent uniform over each
    episode's searchable cells, targets by the same models on searchable cells only (random:
    uniform over them; gaussian: redrawn while masked; equidistant: an offset whose whole
    lattice is searchable; fixed: the one layout, which every mask must leave searchable)."""
    n = mask.shape[0]
    counts = mask.reshape(n, -1).sum(axis=1)
    if (counts < cfg.n_targets + 1).any():
        raise ValueError(f"{cfg.n_targets} targets and the agent need {cfg.n_targets + 1} searchable cells; "
                         f"a mask has {int(counts.min())}")
    rows = np.arange(n)
    if cfg.distribution == "fixed":
        layout = fixed_layout(cfg)
        if not mask[:, layout[:, 1], layout[:, 0]].all():
            raise ValueError("the fixed layout (the lattice centred on the grid) falls on masked cells of "
                             "this field; use another --distribution")
        free = mask.copy()
        free[:, layout[:, 1], layout[:, 0]] = False
        return _uniform_cells(rng, free), np.broadcast_to(layout, (n, cfg.n_targets, 2)).copy()
    agent = _uniform_cells(rng, mask)
    if cfg.distribution == "random":
        wh = cfg.width * cfg.height
        keys = rng.random((n, wh))
        keys[~mask.reshape(n, -1)] = np.inf
        keys[rows, agent[:, 1] * cfg.width + agent[:, 0]] = np.inf
        cells = np.argsort(keys, axis=1)[:, : cfg.n_targets]
        return agent, np.stack([cells % cfg.width, cells // cfg.width], axis=-1).astype(np.int64)
    if cfg.distribution == "gaussian":
        return agent, _gaussian(cfg, rng, agent, mask)
    off = lattice_offsets(cfg)
    span = off.max(axis=0)
    ox, oy = np.arange(cfg.width - span[0]), np.arange(cfg.height - span[1])
    origins = np.stack(np.meshgrid(ox, oy, indexing="xy"), axis=-1).reshape(-1, 2)
    layouts = origins[:, None, :] + off[None]  # (O, R, 2)
    on = mask[:, layouts[..., 1], layouts[..., 0]].all(axis=2)  # (n, O)
    hits = np.any(np.all(layouts[None] == agent[:, None, None, :], axis=-1), axis=-1)
    allowed = on & ~hits
    if not allowed.any(axis=1).all():
        # the agent may stand where the only lattice fits: put it elsewhere on the field
        bad = ~allowed.any(axis=1)
        if not on[bad].any(axis=1).all():
            raise ValueError(f"no offset of the {cfg.n_targets}-target lattice (spacing {cfg.grid_spacing}) lies "
                             "on the searchable cells of a mask; use --distribution random")
        first = layouts[on[bad].argmax(axis=1)]  # (b, R, 2)
        free = mask[bad].copy()
        free[np.arange(int(bad.sum()))[:, None], first[..., 1], first[..., 0]] = False
        agent[bad] = _uniform_cells(rng, free)
        hits = np.any(np.all(layouts[None] == agent[:, None, None, :], axis=-1), axis=-1)
        allowed = on & ~hits
    keys = rng.random(allowed.shape)
    keys[~allowed] = np.inf
    return agent, layouts[np.argmin(keys, axis=1)]
