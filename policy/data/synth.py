"""Dataset synthesis: episodes -> ground-truth plans -> (I, M, a) samples on disk.

Episodes are drawn in chunks, each with its own seed derived from (seed, chunk), solved by
the batched solver and replayed in the batched grid world, recording every active
episode's observation and the solver's action at every step.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from provenance import stamp
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

from ..base import observe
from ..groundtruth import PlanPolicy
from .shards import ShardWriter

ViewFn = Callable[[BatchGridWorld], np.ndarray]


def chunk_seed(seed: int, chunk: int) -> int:
    return int(np.random.SeedSequence([seed, chunk]).generate_state(1, dtype=np.uint64)[0] >> 2)


def _views(view_fn: ViewFn, world: BatchGridWorld) -> np.ndarray:
    """A renderer's frames, checked: a wrong shape would otherwise end up in every shard."""
    v = np.asarray(view_fn(world))
    if v.dtype != np.uint8 or v.ndim != 4 or v.shape[:2] != (world.n, 3):
        raise ValueError(f"view_fn must return (n={world.n}, 3, H, W) uint8 frames, got {v.shape} {v.dtype}")
    return v


def synthesize(
    cfg: GridConfig,
    episodes: int,
    seed: int,
    out: str | Path,
    method: str = "pt",
    shard_size: int = 100_000,
    chunk: int = 2000,
    view_fn: ViewFn | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Write the (I, M, a) samples of `episodes` solved episodes to the dataset directory `out`
    and return it. `view_fn(world) -> (n, 3, H, W) uint8` replaces the grid view I (rendered
    frames, the paper's +S); `method` 'pt' is optimal (lookahead for moving targets)."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1 (got {episodes})")
    writer = ShardWriter(Path(out), shard_size, overwrite)
    done = 0
    bar = tqdm(total=episodes, desc=f"synth {cfg.distribution}/{cfg.motion}", unit="ep", disable=not progress)
    for c in range(0, -(-episodes // chunk)):
        n = min(chunk, episodes - done)
        cs = chunk_seed(seed, c)
        ep = sample_episodes(cfg, n, cs)
        policy = PlanPolicy(method)
        policy.reset(cfg, n, cs, ep)
        world = BatchGridWorld(ep, cs)
        ids = np.arange(done, done + n, dtype=np.int32)
        while not world.done.all():
            obs = observe(world, None if view_fn is None else _views(view_fn, world))
            a = policy.act(obs)
            act = obs.active
            writer.add(obs.views[act], obs.maps[act].astype(np.uint8), a[act].astype(np.int8), ids[act])
            world.step(a)
        done += n
        bar.update(n)
    bar.close()
    meta = stamp(cfg.to_dict() | {"n_actions": cfg.n_actions}, seed, method=method, episodes=episodes,
                 rendered=view_fn is not None)
    return writer.close(meta)
