"""GPS noise in the grid-world evaluation (issue 11): the agent never knows its cell for sure.

The world moves the agent exactly (its truth); the agent only gets a position estimate:
- fixes: every decision a GPS fix, the true cell centre plus N(0, sigma^2) per axis (metres,
  cells of GridConfig-independent size cell_m, 2 m by default as in sim.gridworld.coords);
- estimator: "kalman" fuses the fixes with the moves the agent commanded (a per-axis Kalman
  filter with process noise process_m per move, as the flight's estimator fuses GPS and
  velocity), "fix" uses each fix alone (no memory).
What the agent reads:
- hard map: its most likely cell is treated as exact: positions, the valid-move mask and the
  spatial map M are built from it (the paper's pipeline fed a noisy position);
- probabilistic map: the same positions plus obs.position_prob (the posterior over cells) and
  the expected map M (policy.belief.gps.expected_spatial_map): the paper's future work.
The camera view I is always the truth around the true cell. Static targets, spatial map only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from sim.gridworld import (
    DEFAULT_CELL_M,
    DELTAS,
    BatchGridWorld,
    GridConfig,
    sample_episodes,
    valid_mask,
)
from sim.gridworld.observations import spatial_map

from ..base import Observation, Policy
from ..belief.gps import cell_probabilities_xy, expected_spatial_map
from ..groundtruth import optimal_lengths
from .runner import EvalResult

ESTIMATORS = ("kalman", "fix")


@dataclass(frozen=True)
class GpsNoise:
    sigma_m: float = 1.0
    prob_map: bool = True
    estimator: str = "kalman"
    process_m: float = 0.5
    cell_m: float = DEFAULT_CELL_M

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma_m) and self.sigma_m >= 0):
            raise ValueError(f"sigma_m must be >= 0 (got {self.sigma_m})")
        if self.estimator not in ESTIMATORS:
            raise ValueError(f"estimator must be one of {ESTIMATORS} (got {self.estimator!r})")
        if not self.process_m > 0 or not self.cell_m > 0:
            raise ValueError("process_m and cell_m must be > 0")


class GpsTracker:
    """The agent's side: fixes in, posterior (mean, sd in cells) out, and the maps it builds."""

    def __init__(self, cfg: GridConfig, noise: GpsNoise, n: int, rng: np.random.Generator) -> None:
        self.cfg, self.noise, self.rng = cfg, noise, rng
        self.sig = noise.sigma_m / noise.cell_m
        self.q = noise.process_m / noise.cell_m
        self.mean = np.zeros((n, 2))
        self.var = np.full(n, np.inf)
        self.visited_hard = np.zeros((n, cfg.height, cfg.width), bool)
        self.visited_prob = np.zeros((n, cfg.height, cfg.width))

    def fix(self, truth: np.ndarray, active: np.ndarray) -> None:
        z = truth + self.rng.normal(0.0, self.sig, truth.shape)
        if self.noise.estimator == "fix" or not np.isfinite(self.var).any():
            upd = active | ~np.isfinite(self.var)
            self.mean[upd], self.var[upd] = z[upd], self.sig**2
            return
        k = self.var / (self.var + self.sig**2)
        new = self.mean + k[:, None] * (z - self.mean)
        self.mean = np.where(active[:, None], new, self.mean)
        self.var = np.where(active, (1 - k) * self.var, self.var)

    def moved(self, actions: np.ndarray, active: np.ndarray) -> None:
        """Predict with the commanded moves (the estimator does not know of wall bumps)."""
        if self.noise.estimator != "kalman":
            return
        w, h = self.cfg.width, self.cfg.height
        m = self.mean + DELTAS[actions] * active[:, None]
        self.mean = np.clip(m, [0, 0], [w - 1, h - 1])
        self.var = np.where(active, self.var + self.q**2, self.var)

    def observation(self, views: np.ndarray, t: np.ndarray, active: np.ndarray) -> Observation:
        cfg = self.cfg
        sd = np.sqrt(np.maximum(self.var, 1e-6))
        p = cell_probabilities_xy(self.mean, sd, cfg.width, cfg.height)
        idx = p.reshape(len(p), -1).argmax(axis=1)
        est = np.stack([idx % cfg.width, idx // cfg.width], axis=1).astype(np.int64)
        rows = np.flatnonzero(active)
        self.visited_hard[rows, est[rows, 1], est[rows, 0]] = True
        self.visited_prob[rows] = 1.0 - (1.0 - self.visited_prob[rows]) * (1.0 - p[rows])
        if self.noise.prob_map:
            maps, prob = expected_spatial_map(self.visited_prob, p), p.astype(np.float32)
        else:
            maps, prob = spatial_map(est, self.visited_hard), None
        return Observation(views=views, maps=maps, positions=est,
                           valid=valid_mask(est, cfg.width, cfg.height, cfg.n_actions),
                           t=t.copy(), active=active.copy(), position_prob=prob)


def evaluate_gps(policy: Policy, cfg: GridConfig, episodes: int, seed: int, noise: GpsNoise,
                 batch: int = 5000, progress: bool = True) -> EvalResult:
    """Like runner.evaluate (same episodes for the same seed), with the agent's position
    estimated from noisy GPS fixes. sigma_m == 0 is the exact evaluation."""
    if cfg.moving or cfg.map_variant != "spatial":
        raise ValueError("the GPS evaluation covers static targets with the spatial map")
    if policy.needs_truth:
        raise ValueError(f"{policy.name} reads the truth; GPS noise does not apply to it")
    ep_all = sample_episodes(cfg, episodes, seed)
    optimal = optimal_lengths(ep_all)
    moves, finds, replaced = [], [], []
    bar = tqdm(total=episodes, desc=f"gps {policy.name} {noise.sigma_m} m", unit="ep",
               disable=not progress, leave=False)
    for b0 in range(0, episodes, batch):
        ep = ep_all.subset(slice(b0, b0 + batch))
        n = len(ep)
        policy.reset(cfg, n, seed + b0, None)
        world = BatchGridWorld(ep, seed + b0, off_map=policy.off_map)
        exact = noise.sigma_m == 0
        tracker = None if exact else GpsTracker(cfg, noise, n, np.random.default_rng([seed + b0, 0x6B5]))
        while not world.done.all():
            views, maps = world.observe()
            active = ~world.done
            if tracker is None:
                obs = Observation(views, maps, world.agent.copy(), world.valid_actions(), world.t.copy(), active)
            else:
                tracker.fix(world.agent.astype(np.float64), active)
                obs = tracker.observation(views, world.t, active)
            a = np.asarray(policy.act(obs), dtype=np.int64)
            world.step(a)
            if tracker is not None:
                tracker.moved(np.minimum(a, len(DELTAS) - 1), active)
        moves.append(world.t.copy())
        finds.append(world.find_moves.copy())
        replaced.append(world.replaced.copy())
        bar.update(n)
    bar.close()
    return EvalResult(policy=policy.name, cfg=cfg, seed=seed, moves=np.concatenate(moves), optimal=optimal,
                      find_moves=np.concatenate(finds), loops=None, replaced=np.concatenate(replaced))
