"""Run a team policy on test episodes in lock-step (issue 29): the makespan and Table I's
columns with the makespan as the moves, on exactly the episodes today's single agent meets
(sample_episodes with the same seed; agent 0 starts where the single agent starts)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from sim.gridworld import GridConfig, sample_episodes
from sim.gridworld.team import TeamGridWorld, team_starts

from ..evaluation.metrics import table1_columns
from ..groundtruth import optimal_lengths
from .base import TeamPolicy, team_observe


@dataclass
class TeamResult:
    policy: str
    cfg: GridConfig
    seed: int
    n_agents: int
    #: (n,) joint steps until every target was found (t_e + 1 on failure)
    makespan: np.ndarray
    #: (n,) the single agent's optimal tour (the oracle's moves), for Table I's ratios
    optimal: np.ndarray
    find_moves: np.ndarray
    #: (n, R) which agent recovered each target
    find_agent: np.ndarray
    #: (n, N) moves the world refused by the separation rule; off-map choices replaced
    blocked: np.ndarray
    replaced: np.ndarray

    @property
    def columns(self) -> dict[str, float | None]:
        cols = table1_columns(self.makespan, self.optimal, self.find_moves, None, self.cfg.t_e)
        cols |= {
            "agents": self.n_agents,
            "mean_makespan": float(self.makespan.mean()),
            "p90_makespan": float(np.percentile(self.makespan, 90)),
            "blocked_mean": float(self.blocked.sum(axis=1).mean()),
            "offmap_replaced_mean": float(self.replaced.sum(axis=1).mean()),
        }
        return cols


def evaluate_team(policy: TeamPolicy, cfg: GridConfig, episodes: int, seed: int, n_agents: int,
                  batch: int = 5000, progress: bool = True) -> TeamResult:
    """Like policy.evaluation.evaluate: batch b's policy and world streams are seeded with
    seed + its first episode's index; episode i is the same for every policy and team size."""
    if episodes < 1 or batch < 1:
        raise ValueError(f"episodes and batch must be >= 1 (got {episodes}, {batch})")
    ep_all = sample_episodes(cfg, episodes, seed)
    starts_all = team_starts(ep_all, n_agents)
    out: dict[str, list[np.ndarray]] = {k: [] for k in ("t", "fm", "fa", "bl", "rp")}
    bar = tqdm(total=episodes, desc=f"team {policy.name} x{n_agents}", unit="ep", disable=not progress, leave=False)
    for b0 in range(0, episodes, batch):
        sl = slice(b0, b0 + batch)
        ep = ep_all.subset(sl)
        policy.reset(cfg, len(ep), n_agents, seed + b0)
        world = TeamGridWorld(ep, starts_all[sl], seed + b0)
        while not world.done.all():
            world.step(policy.act(team_observe(world)))
        for key, v in (("t", world.t), ("fm", world.find_moves), ("fa", world.find_agent),
                       ("bl", world.blocked), ("rp", world.replaced)):
            out[key].append(v.copy())
        bar.update(len(ep))
    bar.close()
    return TeamResult(policy.name, cfg, seed, n_agents, np.concatenate(out["t"]), optimal_lengths(ep_all),
                      np.concatenate(out["fm"]), np.concatenate(out["fa"]), np.concatenate(out["bl"]),
                      np.concatenate(out["rp"]))
