"""What a team policy sees and how it decides (issue 29): one joint decision per step for N
agents in each of n episodes, and the separation rule every team policy applies to its moves."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from sim.gridworld import DELTAS, GridConfig
from sim.gridworld.team import TeamGridWorld


@dataclass(frozen=True)
class TeamObservation:
    views: np.ndarray  # (n, N, 3, 3, 3) uint8: each agent's 3 x 3 view
    maps: np.ndarray  # (n, N, 1, h, w) float32: the team's visited map, the agent's own cell marked
    positions: np.ndarray  # (n, N, 2) agent cells (x, y): known to the whole team (beacons)
    valid: np.ndarray  # (n, N, A) bool: moves that stay on the map
    t: np.ndarray  # (n,) joint steps so far
    active: np.ndarray  # (n,) bool: episodes still running


def team_observe(world: TeamGridWorld) -> TeamObservation:
    v, m = world.observe()
    return TeamObservation(views=v, maps=m, positions=world.agents.copy(), valid=world.valid_actions(),
                           t=world.t.copy(), active=~world.done)


class TeamPolicy(ABC):
    #: short name used by the CLI and in result tables
    name: str = "team"

    @abstractmethod
    def reset(self, cfg: GridConfig, n: int, n_agents: int, seed: int) -> None:
        """Start n episodes of n_agents agents. Every random choice draws from a stream of seed."""

    @abstractmethod
    def act(self, obs: TeamObservation) -> np.ndarray:
        """(n, N) int actions; off-map choices are replaced by the world, conflicting moves
        refused by it (sim.gridworld.team)."""


def separate(positions: np.ndarray, prefs: np.ndarray, valid: np.ndarray, order: np.ndarray | None = None) -> np.ndarray:
    """The no-conflict rule of the team policies: (n, N) actions from per-action preferences
    prefs (n, N, A) (higher first). Agents choose in `order` ((n, N) agent indices, default
    0..N-1); each takes its most preferred valid move whose cell is neither the current cell of
    an agent that has not chosen yet nor a cell an earlier agent has taken (so no two agents in one cell and no
    swap through each other; an agent may follow one that has already moved on). An agent
    with no such move (boxed in at a corner) takes its best valid one, which the world refuses
    (it stays). Why this form: N is small, so N sequential rounds vectorised over episodes."""
    n, k, a_n = prefs.shape
    rows = np.arange(n)
    order = np.broadcast_to(np.arange(k), (n, k)) if order is None else np.asarray(order)
    nxt = positions[:, :, None, :] + DELTAS[None, None, :a_n]  # (n, N, A, 2)
    taken = positions.copy()  # (n, N, 2): the cells no one else may take: current, then chosen
    out = np.zeros((n, k), np.int64)
    p = np.where(valid, prefs, -np.inf)
    for m in range(k):
        i = order[:, m]
        cand = nxt[rows, i]  # (n, A, 2)
        hit = np.all(cand[:, :, None] == taken[:, None], axis=-1)  # (n, A, N)
        hit[rows, :, i] = False  # one's own cell (a stay) is free for oneself
        free = ~hit.any(axis=2)
        key = np.where(free, p[rows, i], -np.inf)
        best = key.argmax(axis=1)
        none = ~np.isfinite(key[rows, best])
        best[none] = p[rows[none], i[none]].argmax(axis=1)
        out[rows, i] = best
        taken[rows, i] = np.where(none[:, None], positions[rows, i], nxt[rows, i, best])
    return out
