"""Run any policy on N test episodes in lock-step and collect what Table I needs.

Every policy evaluated with the same (config, episodes, seed) meets exactly the same
episodes, so results are paired and the ratio to the oracle is meaningful per episode.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

from ..base import Policy, observe
from ..groundtruth import optimal_lengths
from .metrics import table1_columns


@dataclass
class EvalResult:
    policy: str
    cfg: GridConfig
    seed: int
    moves: np.ndarray
    optimal: np.ndarray
    find_moves: np.ndarray
    loops: np.ndarray | None
    #: off-map choices the world replaced by a random valid move, per episode
    replaced: np.ndarray | None = None
    #: seconds flown per episode (sim.gridworld.FlightModel: horizontal and vertical speeds)
    flight_s: np.ndarray | None = None
    #: a few episodes kept for plots: start cells, targets at t = 0 and trajectories
    sample_paths: list[np.ndarray] = field(default_factory=list)
    sample_targets: list[np.ndarray] = field(default_factory=list)

    @property
    def columns(self) -> dict[str, float | None]:
        cols = table1_columns(self.moves, self.optimal, self.find_moves, self.loops, self.cfg.t_e)
        if self.replaced is not None:
            cols["offmap_replaced_mean"] = float(self.replaced.mean())
        if self.flight_s is not None:
            cols["mean_flight_s"] = float(self.flight_s.mean())
        return cols


def evaluate(
    policy: Policy,
    cfg: GridConfig,
    episodes: int,
    seed: int,
    batch: int = 5000,
    keep_paths: int = 12,
    progress: bool = True,
    view_fn: Callable[[BatchGridWorld], np.ndarray] | None = None,
    mask: np.ndarray | None = None,
) -> EvalResult:
    """Evaluate in batches of `batch` episodes; episode i is the same for every policy.
    Batch b's policy and world streams are seeded with seed + its first episode's index.
    view_fn replaces the 3 x 3 view I (e.g. rendered camera frames for +S). mask: (h, w) or
    (episodes, h, w) bool searchable cells (a masked field, sim.gridworld.masks), None = the grid."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1 (got {episodes})")
    if batch < 1:
        raise ValueError(f"batch must be >= 1 (got {batch})")
    ep_all = sample_episodes(cfg, episodes, seed) if mask is None else sample_episodes(cfg, episodes, seed, mask)
    optimal = optimal_lengths(ep_all)
    moves: list[np.ndarray] = []
    finds: list[np.ndarray] = []
    loops: list[np.ndarray | None] = []
    replaced: list[np.ndarray] = []
    flight: list[np.ndarray] = []
    paths: list[np.ndarray] = []
    targets: list[np.ndarray] = []
    bar = tqdm(total=episodes, desc=f"eval {policy.name}", unit="ep", disable=not progress, leave=False)
    for b0 in range(0, episodes, batch):
        ep = ep_all.subset(slice(b0, b0 + batch))
        n = len(ep)
        policy.reset(cfg, n, seed + b0, ep if policy.needs_truth else None)
        world = BatchGridWorld(ep, seed + b0, off_map=policy.off_map)
        while not world.done.all():
            obs = observe(world, None if view_fn is None else view_fn(world))
            world.step(policy.act(obs))
        moves.append(world.t.copy())
        finds.append(world.find_moves.copy())
        replaced.append(world.replaced.copy())
        flight.append(world.flight_s.copy())
        loops.append(policy.loops())
        if len(paths) < keep_paths:
            traj = world.trajectories()
            for i in range(min(n, keep_paths - len(paths))):
                paths.append(traj[i, : world.t[i] + 1].astype(np.int64))
                targets.append(ep.targets[i].copy())
        bar.update(n)
    bar.close()
    return EvalResult(
        policy=policy.name,
        cfg=cfg,
        seed=seed,
        moves=np.concatenate(moves),
        optimal=optimal,
        find_moves=np.concatenate(finds),
        loops=None if any(x is None for x in loops) else np.concatenate(loops),  # type: ignore[arg-type]
        replaced=np.concatenate(replaced),
        flight_s=np.concatenate(flight),
        sample_paths=paths,
        sample_targets=targets,
    )
