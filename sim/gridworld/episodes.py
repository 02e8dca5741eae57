"""Episode start configurations, drawn in bulk so that every policy and every solver sees
exactly the same episodes for a given seed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import GridConfig
from .motion import target_paths
from .placement import place


@dataclass(frozen=True)
class Episodes:
    """n episodes. Cells are (x, y) int64. `paths[:, t]` holds target cells at time t
    (after t agent moves), t = 0 .. t_e + 1; for static targets it is None."""

    cfg: GridConfig
    agent: np.ndarray  # (n, 2)
    targets: np.ndarray  # (n, R, 2) at t = 0
    paths: np.ndarray | None  # (n, t_e + 2, R, 2) or None
    seed: int | None = None
    #: (n,) each episode's index in the draw (sample_episodes: 0..n-1; subset keeps them): with
    #: seed it names the episode's own random streams (the detections), so an episode plays
    #: the same in any batch. None: 0..n-1.
    ids: np.ndarray | None = None
    #: (n, h, w) bool searchable cells per episode (sim.gridworld.masks), None = the whole grid
    mask: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.agent.shape[0])

    def targets_at(self, t: np.ndarray | int) -> np.ndarray:
        """Target cells at time t per episode: (n, R, 2). t: scalar or (n,) int."""
        if self.paths is None:
            return self.targets
        t = np.minimum(np.broadcast_to(np.asarray(t), (len(self),)), self.paths.shape[1] - 1)
        return self.paths[np.arange(len(self)), t]

    def episode_ids(self) -> np.ndarray:
        """(n,) int64 episode indices in the draw (ids, or 0..n-1)."""
        return np.arange(len(self), dtype=np.int64) if self.ids is None else np.asarray(self.ids, np.int64)

    def subset(self, idx: np.ndarray | slice) -> Episodes:
        return Episodes(
            self.cfg,
            self.agent[idx],
            self.targets[idx],
            None if self.paths is None else self.paths[idx],
            self.seed,
            self.episode_ids()[idx],
            None if self.mask is None else self.mask[idx],
        )


def world_rng(seed: int) -> np.random.Generator:
    """The stream that draws the world (placement and target motion) for a seed."""
    return np.random.default_rng([seed, 0x57A7E])


def sample_episodes(cfg: GridConfig, n: int, seed: int, mask: np.ndarray | None = None) -> Episodes:
    """mask: (h, w) or (n, h, w) bool searchable cells (sim.gridworld.masks); None = the
    whole grid, the same episodes as ever."""
    if n < 1:
        raise ValueError(f"need at least one episode (got {n})")
    rng = world_rng(seed)
    ids = np.arange(n, dtype=np.int64)
    if mask is None:
        agent, targets = place(cfg, rng, n)
        paths = target_paths(cfg, rng, targets) if cfg.moving else None
        return Episodes(cfg, agent, targets, paths, seed, ids)
    from .masks import episode_masks
    from .placement import place_masked

    masks = episode_masks(mask, n, cfg.height, cfg.width)
    agent, targets = place_masked(cfg, rng, masks)
    paths = target_paths(cfg, rng, targets, masks) if cfg.moving else None
    return Episodes(cfg, agent, targets, paths, seed, ids, masks)


def detection_rng(seed: int | None, episode_id: int) -> np.random.Generator:
    """An episode's own stream for what the camera detects (altitude levels with imperfect
    detection): from the episodes' seed and the episode's index, not the batch."""
    return np.random.default_rng([0 if seed is None else int(seed) % (1 << 64), 0xDE7EC7, int(episode_id)])
