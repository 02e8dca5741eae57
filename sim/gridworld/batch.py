"""Many grid-world episodes stepped in lock-step with numpy: the engine behind dataset
synthesis, evaluation and the gymnasium wrapper.

Time t counts the agent's moves. Every action counts one move (a stay, and a random valid
move that replaces an off-map choice, too). A target is recovered when the agent stands on
its cell at the same time. An episode ends when all targets are found or when moves exceed
t_e (a failed episode records t_e + 1 moves).

Altitude levels (cfg.levels > 1, docs/altitude.md): the agent starts at level 1; climb and
descend are one move each and change only the level; a target is recovered only at level 1;
the view is the highest level's window of detections, drawn from each episode's own stream
(episodes.detection_rng) after every move; visited marks the cells flown over at level 1
(where a target would have been recovered). flight_s adds each move's seconds (FlightModel).
"""

from __future__ import annotations

import numpy as np

from .actions import DELTAS, LEVEL_DELTAS
from .config import GridConfig
from .detection import FLIGHT, FlightModel
from .episodes import Episodes, detection_rng
from .masks import blocked_view, neighbour_valid
from .observations import AGENT_VALUE, LEVEL_VIEW_CHANNELS, MET_VALUE, VIEW_CHANNELS, VISITED_VALUE


class BatchGridWorld:
    def __init__(self, episodes: Episodes, seed: int = 0, off_map: str = "random",
                 flight: FlightModel = FLIGHT) -> None:
        """off_map: 'random' replaces an off-map action by a random valid move (the paper's
        rule, Section V-A); 'stay' leaves the agent in place (a wall bump, as the DRQN baseline
        was trained). Either way it counts one move. flight: the speeds for flight_s."""
        if off_map not in ("random", "stay"):
            raise ValueError(f"off_map must be 'random' or 'stay' (got {off_map!r})")
        self.off_map = off_map
        cfg: GridConfig = episodes.cfg
        self.cfg, self.episodes = cfg, episodes
        n, r, w, h = len(episodes), cfg.n_targets, cfg.width, cfg.height
        self.n = n
        self._rows = np.arange(n)
        #: the stream that replaces off-map actions; separate from the world's stream
        self.rng = np.random.default_rng([seed, 0xAC7])
        self.agent = episodes.agent.astype(np.int64).copy()
        self.t = np.zeros(n, dtype=np.int64)
        self.found = np.zeros((n, r), dtype=bool)
        self.find_moves = np.full((n, r), -1, dtype=np.int64)
        self.visited = np.zeros((n, h, w), dtype=bool)
        self.visited[self._rows, self.agent[:, 1], self.agent[:, 0]] = True
        self.met = np.zeros((n, h, w), dtype=bool)
        self.trail = np.zeros((n, h, w), dtype=np.float32)
        self.recoveries = np.zeros((n, h, w), dtype=np.float32)
        if cfg.map_variant == "spatiotemporal":
            self.trail[self._rows, self.agent[:, 1], self.agent[:, 0]] = cfg.trail_value
        self.done = np.zeros(n, dtype=bool)
        # the spatial map without the agent, kept up to date in step (observe copies it): the
        # map from visited/met at every observation cost more than the step itself
        self._map = np.zeros((n, h, w), dtype=np.float32)
        self._map[self._rows, self.agent[:, 1], self.agent[:, 0]] = VISITED_VALUE
        #: (n, h, w) bool searchable cells (sim.gridworld.masks), None = the whole grid
        self.mask = episodes.mask
        if self.mask is not None and cfg.map_variant != "spatiotemporal":
            # the map M shows masked cells as visited: nothing to search there (docs/gridworld.md)
            self._map[~self.mask] = VISITED_VALUE
        self.replaced = np.zeros(n, dtype=np.int64)
        self._history: list[np.ndarray] = [self.agent.astype(np.int16)]
        #: (n,) altitude level of each agent (1 = the paper's height)
        self.level = np.ones(n, dtype=np.int64)
        #: (n,) seconds flown so far (FlightModel: horizontal and vertical speeds)
        self.flight_s = np.zeros(n, dtype=np.float64)
        #: (n,) targets recovered by the last move
        self.found_now = np.zeros(n, dtype=np.int64)
        self.flight = flight
        self._step_s = flight.step_seconds(cfg.levels)
        #: the view is drawn (levels > 1 or an imperfect level 1): detections, not the truth
        self.sampled = not cfg.perfect_detection
        if self.sampled:
            self._setup_detection(episodes)
        self._check_start()

    # ------------------------------------------------------------------ detection (levels)
    def _setup_detection(self, episodes: Episodes) -> None:
        cfg = self.cfg
        rmax = cfg.view_radius
        self._win = 2 * rmax + 1
        off = np.arange(-rmax, rmax + 1)
        self._ring = np.maximum(np.abs(off)[:, None], np.abs(off)[None, :])  # (W, W)
        p, fa = cfg.detection.ring_table(cfg.levels)
        self._p_ring = np.array([[0.0] * (rmax + 1)] + p)  # (L + 1, rmax + 1), row 0 unused
        self._fa = np.array([0.0] + fa)
        self._det_rngs = [detection_rng(episodes.seed, i) for i in episodes.episode_ids()]
        self.detections = np.zeros((self.n, self._win, self._win), dtype=bool)
        self._draw(np.ones(self.n, dtype=bool))

    def _window_cells(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ys (n, W), xs (n, W), inside (n, W, W)) of the highest level's window per agent."""
        rmax = self.cfg.view_radius
        off = np.arange(-rmax, rmax + 1)
        ys, xs = self.agent[:, 1, None] + off, self.agent[:, 0, None] + off
        inside = ((ys >= 0) & (ys < self.cfg.height))[:, :, None] & ((xs >= 0) & (xs < self.cfg.width))[:, None, :]
        return ys, xs, inside

    def _draw(self, rows: np.ndarray) -> None:
        """What the camera detects now, for the episodes in rows (bool (n,)): each target in
        the level's footprint with p_d(level, ring), each empty cell in it with the level's
        false-alarm rate. One block of W * W uniforms per episode and move, from its own stream."""
        idx = np.flatnonzero(rows)
        if not len(idx):
            return
        w = self._win
        u = np.stack([self._det_rngs[i].random(w * w) for i in idx]).reshape(len(idx), w, w)
        rmax = self.cfg.view_radius
        _, _, inside = self._window_cells()
        tg = self.targets()[idx]
        dx = tg[..., 0] - self.agent[idx, None, 0] + rmax
        dy = tg[..., 1] - self.agent[idx, None, 1] + rmax
        near = (dx >= 0) & (dx < w) & (dy >= 0) & (dy < w)
        occ = np.zeros((len(idx), w, w), dtype=bool)
        ep, _ = np.nonzero(near)
        occ[ep, dy[near], dx[near]] = True
        lvl = self.level[idx]
        footprint = (self._ring[None] <= lvl[:, None, None]) & inside[idx]
        p = self._p_ring[lvl][:, self._ring]  # (m, W, W)
        fa = self._fa[lvl][:, None, None]
        self.detections[idx] = footprint & np.where(occ, u < p, u < fa)

    def _check_start(self) -> None:
        on = np.all(self.targets() == self.agent[:, None, :], axis=-1)
        if on.any():
            raise ValueError("an episode starts with the agent on a target; placement is broken")

    @property
    def n_actions(self) -> int:
        return self.cfg.n_actions

    def targets(self) -> np.ndarray:
        """Current target cells (n, R, 2). Truth: only solvers, the oracle and scorers read it."""
        return self.episodes.targets_at(self.t)

    def valid_actions(self) -> np.ndarray:
        """(n, n_actions) bool: which actions keep each agent on the map (actions.valid_mask; a
        masked cell is off the map); with levels, stay only for moving targets, climb below the
        top, descend above level 1."""
        if self.mask is not None:  # a masked cell is off the map
            if self.cfg.levels == 1:
                return neighbour_valid(self.mask, self.agent, self.n_actions)
            moves = neighbour_valid(self.mask, self.agent, 4)
            cols = [moves[:, k] for k in range(4)] + [np.ones(self.n, dtype=bool)]
        else:
            x, y = self.agent[:, 0], self.agent[:, 1]
            cols = [y > 0, y < self.cfg.height - 1, x > 0, x < self.cfg.width - 1, np.ones(self.n, dtype=bool)]
        if self.cfg.levels > 1:
            cols[4] = np.full(self.n, self.cfg.moving)
            cols += [self.level < self.cfg.levels, self.level > 1]
        return np.stack(cols[: self.n_actions], axis=1)

    def observe(self) -> tuple[np.ndarray, np.ndarray]:
        """(views (n, 3, 3, 3) uint8, maps (n, C, h, w) float32) for every episode: the same as
        observations.views and spatial_map, computed from the target and agent cells directly.
        With levels > 1 the views are (n, 4, W, W), W = 2 L + 1 (observations.LEVEL_VIEW_CHANNELS)."""
        cfg = self.cfg
        x, y = self.agent[:, 0], self.agent[:, 1]
        if self.sampled:
            v = self._sampled_views()
        else:
            v = self._views()
        if cfg.map_variant == "spatiotemporal":
            m = np.stack([self.trail, self.recoveries], axis=1)
        else:
            m = self._map.copy()
            m[self._rows, y, x] = AGENT_VALUE
            m = m[:, None]
        return v, m

    def _sampled_views(self) -> np.ndarray:
        """The detections in the highest level's window: channels (detection, off-map, agent,
        outside this level's footprint); (3, 3, 3) without the last channel where levels == 1."""
        ys, xs, inside = self._window_cells()
        w = self._win
        chans = LEVEL_VIEW_CHANNELS if self.cfg.levels > 1 else VIEW_CHANNELS
        v = np.zeros((self.n, chans, w, w), dtype=np.uint8)
        v[:, 0] = self.detections
        v[:, 1] = ~inside
        v[:, 2, w // 2, w // 2] = 1
        if chans > VIEW_CHANNELS:
            v[:, 3] = inside & (self._ring[None] > self.level[:, None, None])
        return v

    def _views(self) -> np.ndarray:
        """The paper's 3 x 3 view of the truth (perfect detection at level 1)."""
        cfg = self.cfg
        n, w, h = self.n, cfg.width, cfg.height
        x, y = self.agent[:, 0], self.agent[:, 1]
        v = np.zeros((n, VIEW_CHANNELS, 3, 3), dtype=np.uint8)
        tg = self.targets()
        dx, dy = tg[..., 0] - x[:, None] + 1, tg[..., 1] - y[:, None] + 1  # (n, R) in 0..2 when in view
        near = (dx >= 0) & (dx <= 2) & (dy >= 0) & (dy <= 2)
        ep, _ = np.nonzero(near)
        v[ep, 0, dy[near], dx[near]] = 1
        off_rows = np.stack([y == 0, np.zeros(n, dtype=bool), y == h - 1], axis=1)  # (n, 3)
        off_cols = np.stack([x == 0, np.zeros(n, dtype=bool), x == w - 1], axis=1)
        v[:, 1] = off_rows[:, :, None] | off_cols[:, None, :]
        if self.mask is not None:  # masked cells read like off-map ones
            v[:, 1] = blocked_view(self.mask, self.agent)
        v[:, 2, 1, 1] = 1
        return v

    def step(self, actions: np.ndarray) -> np.ndarray:
        """Apply one action per episode (ignored where done). Returns targets found (n,)."""
        a = np.asarray(actions, dtype=np.int64).copy()
        if a.shape != (self.n,):
            raise ValueError(f"expected {self.n} actions, got shape {a.shape}")
        if (a < 0).any() or (a >= self.n_actions).any():
            raise ValueError(f"actions must be in 0..{self.n_actions - 1} for this config")
        active = ~self.done
        valid = self.valid_actions()
        bad = active & ~valid[self._rows, a]
        if bad.any():
            self.replaced[bad] += 1
            if self.off_map == "random":
                keys = self.rng.random((int(bad.sum()), self.n_actions))
                keys[~valid[bad]] = -1.0
                a[bad] = keys.argmax(axis=1)
        rows = self._rows[active]
        move = active & ~(bad if self.off_map == "stay" else np.zeros_like(bad))
        self.agent[move] += DELTAS[a[move]]
        self.t[active] += 1
        before = self.level.copy()
        if self.cfg.levels > 1:
            self.level[move] += LEVEL_DELTAS[a[move]]
        self.flight_s[active] += self._step_s[before[active], self.level[active]]
        low = None
        vrows = rows
        if self.cfg.levels > 1:
            low = self.level == 1
            vrows = rows[low[rows]]  # visited and the map: at level 1 only
        ay, ax = self.agent[vrows, 1], self.agent[vrows, 0]
        self.visited[vrows, ay, ax] = True
        cell = self._map[vrows, ay, ax]
        self._map[vrows, ay, ax] = np.maximum(cell, VISITED_VALUE)  # a met cell stays MET_VALUE
        if self.cfg.map_variant == "spatiotemporal":
            for grid in (self.trail, self.recoveries):
                g = grid[rows]
                np.subtract(g, 1.0, out=g, where=g > 0)
                grid[rows] = g
            # the trail marks where the agent is, at any level
            self.trail[rows, self.agent[rows, 1], self.agent[rows, 0]] = self.cfg.trail_value
        tg = self.targets()
        hits = (tg[..., 0] == self.agent[:, None, 0]) & (tg[..., 1] == self.agent[:, None, 1]) & ~self.found
        hits &= active[:, None]
        if low is not None:
            hits &= low[:, None]
        newly = hits.sum(axis=1)
        self.found_now = newly
        if newly.any():
            self.found |= hits
            self.find_moves[hits] = np.broadcast_to(self.t[:, None], hits.shape)[hits]
            got = newly > 0
            self.met[self._rows[got], self.agent[got, 1], self.agent[got, 0]] = True
            if self.cfg.map_variant == "memory":
                self._map[self._rows[got], self.agent[got, 1], self.agent[got, 0]] = MET_VALUE
            self.recoveries[self._rows[got], self.agent[got, 1], self.agent[got, 0]] = self.cfg.trail_value
        self.done |= self.found.all(axis=1) | (self.t > self.cfg.t_e)
        self._history.append(self.agent.astype(np.int16))
        if self.sampled:
            self._draw(active & ~self.done)
        return newly

    def run(self, act, max_steps: int | None = None) -> None:
        """Step until every episode is done; `act(world) -> (n,) actions`."""
        limit = self.cfg.t_e + 1 if max_steps is None else max_steps
        for _ in range(limit):
            if self.done.all():
                break
            self.step(act(self))

    def trajectories(self) -> np.ndarray:
        """(n, steps + 1, 2) agent cells over time (frozen once an episode is done)."""
        return np.stack(self._history, axis=1)

    @property
    def success(self) -> np.ndarray:
        return self.found.all(axis=1)
