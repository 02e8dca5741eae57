"""Several UAVs in one grid-world episode (issue 29): one joint step moves every agent once.

Batched like BatchGridWorld: n episodes of one GridConfig, N agents each, arrays (n, N, ...).
The episodes are today's (sample_episodes: the same targets and target paths); agent 0 starts
where today's single agent starts, agents 1..N-1 on cells drawn uniformly from those free of
targets and of the other agents (team_starts, its own stream), so N = 1 is today's world.

Rules (docs/fleet.md):
- time t counts joint steps; each step every agent of a running episode makes one move (an
  off-map choice is replaced by a random valid move, Section V-A, from the world's stream
  drawn exactly as BatchGridWorld draws it, so N = 1 replays today's episodes bit for bit);
- separation: at most one agent per cell and no two agents swapping cells through each other.
  The world enforces it: a move into a cell another agent holds after the step, or a swap, is
  refused and the agent stays where it is (a bump, counted in `blocked`; it still counts as
  the agent's move). Where two agents head for one free cell the lower index gets it. The
  team policies never propose such moves (policy.team.separation); the world's rule is the
  guarantee;
- a target is recovered by whichever agent stands on its cell at the same time (find_agent
  says which); the episode ends when all are found or t > t_e; its makespan is t then.

Single height only (levels = 1, a perfect view) and no masks: the paper's world, N times.
"""

from __future__ import annotations

import numpy as np

from .actions import DELTAS
from .config import ConfigError
from .episodes import Episodes
from .observations import AGENT_VALUE, VIEW_CHANNELS, VISITED_VALUE

#: the most agents a team may have (the conflict rule compares every pair)
MAX_AGENTS = 16


def check_team(episodes: Episodes, n_agents: int) -> None:
    """The team world's limits, as one clear error each."""
    cfg = episodes.cfg
    if not 1 <= n_agents <= MAX_AGENTS:
        raise ConfigError(f"n_agents must be in 1..{MAX_AGENTS} (got {n_agents})")
    if cfg.levels != 1 or not cfg.perfect_detection:
        raise ConfigError(f"the team world flies one height with a perfect view (got levels={cfg.levels})")
    if episodes.mask is not None:
        raise ConfigError("the team world has no masked fields yet (episodes carry a mask)")
    free = cfg.width * cfg.height - cfg.n_targets
    if n_agents > free:
        raise ConfigError(f"{n_agents} agents and {cfg.n_targets} targets do not fit a "
                          f"{cfg.width} x {cfg.height} grid")


def team_rng(seed: int | None, n_agents: int) -> np.random.Generator:
    """The stream that places agents 1..N-1: separate from the world's and the policies'."""
    return np.random.default_rng([0 if seed is None else int(seed) % (1 << 64), 0x7EA4, n_agents])


def team_starts(episodes: Episodes, n_agents: int) -> np.ndarray:
    """(n, N, 2) start cells: agent 0 at episodes.agent, the others uniform over the cells free
    of the targets (at t = 0) and of the agents placed before them, and on a masked field's
    searchable cells (episodes.mask; the same draws: an unmasked field's starts are unchanged).
    Drawn for the whole draw at once (the runner subsets it with the episodes), from
    team_rng(episodes.seed, N)."""
    cfg, n = episodes.cfg, len(episodes)
    if episodes.mask is None and cfg.levels == 1:
        check_team(episodes, n_agents)
    else:  # a fleet flight's starts on a masked field or with levels: the placement's limits only
        free = int(np.asarray(episodes.mask, bool).reshape(n, -1).sum(axis=1).min()) if episodes.mask is not None \
            else cfg.width * cfg.height
        if not 1 <= n_agents <= min(MAX_AGENTS, free - cfg.n_targets):
            raise ConfigError(f"{n_agents} agents and {cfg.n_targets} targets do not fit the field's {free} "
                              f"searchable cells (at most {MAX_AGENTS} agents)")
    h, w = cfg.height, cfg.width
    starts = np.zeros((n, n_agents, 2), np.int64)
    starts[:, 0] = episodes.agent
    taken = np.zeros((n, h * w), bool)
    rows = np.arange(n)
    tg = episodes.targets
    taken[rows[:, None], tg[..., 1] * w + tg[..., 0]] = True
    taken[rows, episodes.agent[:, 1] * w + episodes.agent[:, 0]] = True
    if episodes.mask is not None:  # a masked field: no one starts off it
        taken |= ~np.asarray(episodes.mask, bool).reshape(n, h * w)
    rng = team_rng(episodes.seed, n_agents)
    for k in range(1, n_agents):
        keys = rng.random((n, h * w))
        keys[taken] = -1.0
        idx = keys.argmax(axis=1)
        taken[rows, idx] = True
        starts[:, k] = np.stack([idx % w, idx // w], axis=1)
    return starts


class TeamGridWorld:
    """n episodes, N agents each, stepped jointly. See the module docstring for the rules."""

    def __init__(self, episodes: Episodes, starts: np.ndarray, seed: int = 0) -> None:
        starts = np.asarray(starts, np.int64)
        if starts.ndim != 3 or starts.shape[0] != len(episodes) or starts.shape[2] != 2:
            raise ValueError(f"starts must be ({len(episodes)}, N, 2) cells (got {starts.shape})")
        check_team(episodes, starts.shape[1])
        cfg = episodes.cfg
        self.cfg, self.episodes = cfg, episodes
        n, k = starts.shape[:2]
        self.n, self.n_agents = n, k
        self._rows = np.arange(n)
        same = np.all(starts[:, :, None] == starts[:, None, :], axis=-1) & ~np.eye(k, dtype=bool)
        if same.any():
            raise ValueError("two agents start on one cell")
        #: the stream that replaces off-map actions: BatchGridWorld's, drawn the same way
        self.rng = np.random.default_rng([seed, 0xAC7])
        self.agents = starts.copy()
        self.t = np.zeros(n, np.int64)
        r = cfg.n_targets
        self.found = np.zeros((n, r), bool)
        self.find_moves = np.full((n, r), -1, np.int64)
        #: (n, R) which agent recovered each target (-1: not yet)
        self.find_agent = np.full((n, r), -1, np.int64)
        #: (n, h, w) cells any agent has stood on
        self.visited = np.zeros((n, cfg.height, cfg.width), bool)
        self._mark_visited(~np.zeros(n, bool))
        self.done = np.zeros(n, bool)
        #: (n, N) off-map choices replaced by a random valid move; moves refused by separation
        self.replaced = np.zeros((n, k), np.int64)
        self.blocked = np.zeros((n, k), np.int64)
        self._history: list[np.ndarray] = [self.agents.astype(np.int16)]
        on = np.all(self.targets()[:, None] == self.agents[:, :, None], axis=-1)
        if on.any():
            raise ValueError("an episode starts with an agent on a target; placement is broken")

    @property
    def n_actions(self) -> int:
        return self.cfg.n_actions

    def targets(self) -> np.ndarray:
        """(n, R, 2) current target cells. Truth: only scorers read it."""
        return self.episodes.targets_at(self.t)

    def _mark_visited(self, rows: np.ndarray) -> None:
        e = np.broadcast_to(self._rows[:, None], self.agents.shape[:2])[rows]
        self.visited[e, self.agents[rows, :, 1], self.agents[rows, :, 0]] = True

    def valid_actions(self) -> np.ndarray:
        """(n, N, n_actions) bool: the moves that keep each agent on the map (other agents
        are not obstacles here: the separation rule refuses a conflicting move in step)."""
        x, y = self.agents[..., 0], self.agents[..., 1]
        ones = np.ones_like(x, dtype=bool)
        cols = [y > 0, y < self.cfg.height - 1, x > 0, x < self.cfg.width - 1, ones]
        return np.stack(cols[: self.n_actions], axis=-1)

    def observe(self) -> tuple[np.ndarray, np.ndarray]:
        """(views (n, N, 3, 3, 3) uint8, maps (n, N, 1, h, w) float32): each agent's 3 x 3 view
        of the targets (observations.views' channels), and the team's visited map with the
        agent's own cell marked AGENT_VALUE (the other agents do not show on the map)."""
        cfg = self.cfg
        n, k, h, w = self.n, self.n_agents, cfg.height, cfg.width
        x, y = self.agents[..., 0], self.agents[..., 1]
        v = np.zeros((n, k, VIEW_CHANNELS, 3, 3), np.uint8)
        tg = self.targets()
        dx = tg[:, None, :, 0] - x[..., None] + 1  # (n, N, R)
        dy = tg[:, None, :, 1] - y[..., None] + 1
        near = (dx >= 0) & (dx <= 2) & (dy >= 0) & (dy <= 2)
        e, a, _ = np.nonzero(near)
        v[e, a, 0, dy[near], dx[near]] = 1
        zeros = np.zeros_like(x, dtype=bool)
        off_rows = np.stack([y == 0, zeros, y == h - 1], axis=-1)  # (n, N, 3)
        off_cols = np.stack([x == 0, zeros, x == w - 1], axis=-1)
        v[:, :, 1] = off_rows[..., :, None] | off_cols[..., None, :]
        v[:, :, 2, 1, 1] = 1
        m = np.repeat((self.visited.astype(np.float32) * VISITED_VALUE)[:, None, None], k, axis=1)
        ee, aa = np.nonzero(np.ones((n, k), bool))
        m[ee, aa, 0, y[ee, aa], x[ee, aa]] = AGENT_VALUE
        return v, m

    def _separate(self, cur: np.ndarray, dest: np.ndarray, moving: np.ndarray) -> np.ndarray:
        """(n, N) bool: moves refused by the separation rule (see the module docstring).
        Blocks only grow, so the loop ends after at most N rounds with every destination
        distinct and no swap."""
        k = self.n_agents
        blocked = np.zeros(moving.shape, bool)
        for _ in range(k + 1):
            d = np.where((blocked | ~moving)[..., None], cur, dest)
            stays = blocked | ~moving
            new = np.zeros_like(blocked)
            for i in range(k):
                for j in range(i + 1, k):
                    clash = np.all(d[:, i] == d[:, j], axis=-1)
                    # the agent already in the cell keeps it; else the lower index gets it
                    new[:, j] |= clash & ~stays[:, j]
                    new[:, i] |= clash & stays[:, j] & ~stays[:, i]
                    swap = (np.all(d[:, i] == cur[:, j], axis=-1) & np.all(d[:, j] == cur[:, i], axis=-1)
                            & ~stays[:, i] & ~stays[:, j])
                    new[:, i] |= swap
                    new[:, j] |= swap
            new &= ~blocked
            if not new.any():
                break
            blocked |= new
        return blocked

    def step(self, actions: np.ndarray) -> np.ndarray:
        """One joint step: actions (n, N), ignored where done. Returns targets found (n,)."""
        a = np.asarray(actions, np.int64).copy()
        if a.shape != (self.n, self.n_agents):
            raise ValueError(f"expected ({self.n}, {self.n_agents}) actions, got shape {a.shape}")
        if (a < 0).any() or (a >= self.n_actions).any():
            raise ValueError(f"actions must be in 0..{self.n_actions - 1} for this config")
        active = ~self.done
        act2 = np.broadcast_to(active[:, None], a.shape)
        valid = self.valid_actions()
        bad = act2 & ~np.take_along_axis(valid, a[..., None], axis=-1)[..., 0]
        if bad.any():  # row-major over (episode, agent): N = 1 draws as BatchGridWorld does
            self.replaced[bad] += 1
            keys = self.rng.random((int(bad.sum()), self.n_actions))
            keys[~valid[bad]] = -1.0
            a[bad] = keys.argmax(axis=1)
        cur = self.agents
        dest = cur + DELTAS[a]
        moving = act2 & np.any(dest != cur, axis=-1)
        blocked = self._separate(cur, dest, moving) if self.n_agents > 1 else np.zeros_like(moving)
        self.blocked[blocked] += 1
        go = moving & ~blocked
        self.agents = np.where(go[..., None], dest, cur)
        self.t[active] += 1
        self._mark_visited(active)
        tg = self.targets()
        on = np.all(tg[:, None] == self.agents[:, :, None], axis=-1) & act2[..., None]  # (n, N, R)
        hits = on.any(axis=1) & ~self.found
        newly = hits.sum(axis=1)
        if newly.any():
            self.found |= hits
            self.find_moves[hits] = np.broadcast_to(self.t[:, None], hits.shape)[hits]
            self.find_agent[hits] = on.argmax(axis=1)[hits]
        self.done |= self.found.all(axis=1) | (self.t > self.cfg.t_e)
        self._history.append(self.agents.astype(np.int16))
        return newly

    def trajectories(self) -> np.ndarray:
        """(n, steps + 1, N, 2) agent cells over time (frozen once an episode is done)."""
        return np.stack(self._history, axis=1)

    @property
    def makespan(self) -> np.ndarray:
        """(n,) joint steps until every target was found (t_e + 1 where the episode failed)."""
        return self.t.copy()

    @property
    def success(self) -> np.ndarray:
        return self.found.all(axis=1)
