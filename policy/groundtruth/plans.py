"""Ground-truth decision makers: PT (oracle) and CU as batch policies, and the solver entry
points that turn episodes into action sequences and optimal lengths.

They are named as what they are: they read the episodes' truth (`needs_truth = True`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.gridworld import BatchGridWorld, Episodes, GridConfig

from ..base import Observation, Policy
from .legs import manhattan, step_towards
from .lookahead import intercept, lookahead_dp
from .pt import held_karp


def optimal_lengths(episodes: Episodes, seed: int | None = None) -> np.ndarray:
    """|S_GO| per episode: PT (Held-Karp) for static targets, lookahead PT for moving ones."""
    rng = None if seed is None else np.random.default_rng(seed)
    if episodes.mask is not None:
        from .masked import held_karp_masked, lookahead_dp_masked

        if episodes.paths is not None:
            return lookahead_dp_masked(episodes.agent, episodes.paths, episodes.mask, rng)[0]
        return held_karp_masked(episodes.agent, episodes.targets, episodes.mask, rng)[0]
    if episodes.paths is None:
        return held_karp(episodes.agent, episodes.targets, rng)[0]
    return lookahead_dp(episodes.agent, episodes.paths, rng)[0]


class PlanPolicy(Policy):
    """Follows the optimal order ('pt', named oracle) or the closest unvisited target ('cu')."""

    needs_truth = True

    def __init__(self, method: str = "pt") -> None:
        if method not in ("pt", "cu"):
            raise ValueError(f"method must be 'pt' or 'cu' (got {method!r})")
        self.method = method
        self.name = "oracle" if method == "pt" else "cu"

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        if episodes is None or len(episodes) != n:
            raise ValueError(f"{self.name} needs the {n} episodes' truth")
        if self.method == "cu" and episodes.paths is not None:
            raise ValueError("CU is defined for static targets only (the paper's Section IV-A)")
        self.ep = episodes
        self.rng = np.random.default_rng([seed, 0xC0DE])
        self.found = np.zeros((n, cfg.n_targets), dtype=bool)
        self.rows = np.arange(n)
        self.mask = episodes.mask
        if self.mask is not None:
            if self.method == "cu":
                raise ValueError("cu on masked fields: not implemented (the oracle, pt, is)")
            from .masked import held_karp_masked, lookahead_dp_masked, table_metric

            if episodes.paths is None:
                _, self.order = held_karp_masked(episodes.agent, episodes.targets, self.mask, self.rng)
            else:
                _, self.order = lookahead_dp_masked(episodes.agent, episodes.paths, self.mask, self.rng)
                self._metric = table_metric(self.mask)
            return
        if self.method == "pt":
            if episodes.paths is None:
                _, self.order = held_karp(episodes.agent, episodes.targets, self.rng)
            else:
                _, self.order = lookahead_dp(episodes.agent, episodes.paths, self.rng)

    def _current_goal(self) -> np.ndarray:
        """Index of the target each episode chases now."""
        if self.method == "pt":
            done = np.take_along_axis(self.found, self.order, axis=1)
            k = np.argmin(done, axis=1)  # first not-found position in the order
            return self.order[self.rows, k]
        raise AssertionError

    def act(self, obs: Observation) -> np.ndarray:
        tg = self.ep.targets_at(obs.t)
        self.found |= np.all(tg == obs.positions[:, None, :], axis=-1)
        if self.method == "cu":
            d = manhattan(tg, obs.positions[:, None, :]).astype(np.float64)
            e = np.sqrt(((tg - obs.positions[:, None, :]) ** 2).sum(-1))
            key = np.where(self.found, np.inf, d + e / (2 * (d.max() + 2) * 10))
            goal = tg[self.rows, key.argmin(axis=1)]
            return np.where(self.found.all(1), 0, step_towards(obs.positions, goal, self.rng))
        k = self._current_goal()
        if self.mask is not None:  # shortest paths around the holes
            from sim.gridworld.masks import neighbour_valid

            from .masked import move_towards

            valid = neighbour_valid(self.mask, obs.positions, 5)
            if self.ep.paths is None:
                goal = tg[self.rows, k]
                a = move_towards(self.mask, obs.positions, goal, valid, self.rng)
                return np.where(self.found.all(1), 0, a)
            _, cell = intercept(self.ep.paths, k, obs.positions, obs.t, metric=self._metric)
            a = move_towards(self.mask, obs.positions, cell, valid, self.rng)  # Action.N once there: wait
            return np.where(self.found.all(1), 4, a)
        if self.ep.paths is None:
            goal = tg[self.rows, k]
            return np.where(self.found.all(1), 0, step_towards(obs.positions, goal, self.rng))
        t_hit, cell = intercept(self.ep.paths, k, obs.positions, obs.t)
        a = step_towards(obs.positions, cell, self.rng)  # Action.N once there: wait
        return np.where(self.found.all(1), 4, a)


@dataclass(frozen=True)
class Plans:
    actions: np.ndarray  # (n, L) int8, -1 after the episode ends
    lengths: np.ndarray  # (n,) moves


def solve(episodes: Episodes, method: str = "pt", seed: int = 0) -> Plans:
    """Run the solver through the grid world and return the action sequences it took."""
    n = len(episodes)
    policy = PlanPolicy(method)
    policy.reset(episodes.cfg, n, seed, episodes)
    world = BatchGridWorld(episodes, seed)
    cols: list[np.ndarray] = []
    blank = np.zeros((n, 0), dtype=np.uint8)
    while not world.done.all():
        # the solver reads positions and time only: skip rendering views and maps
        obs = Observation(blank, blank, world.agent.copy(), blank, world.t.copy(), ~world.done)
        a = policy.act(obs)
        cols.append(np.where(world.done, -1, a).astype(np.int8))
        world.step(a)
    return Plans(np.stack(cols, axis=1) if cols else np.zeros((n, 0), np.int8), world.t.copy())
