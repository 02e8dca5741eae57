"""The batched grid world (batch.py) with torch tensors: the same engine, rule for rule, on a
GPU when one is present (or any device asked for).

Episodes are the same for a seed: placement and target motion are drawn by the numpy sampler
(episodes.py) and moved to the device, and the off-map replacement keys come from the same
numpy stream as BatchGridWorld's, drawn for the same rows in the same order. So on CPU a run is
identical to the numpy engine's, step for step (tests/sim/gridworld/test_torch_batch.py); on a
GPU only the device differs. Observations and counters are tensors on the device.
"""

from __future__ import annotations

import numpy as np
import torch

from .actions import DELTAS
from .episodes import Episodes
from .observations import AGENT_VALUE, MET_VALUE, VIEW_CHANNELS, VISITED_VALUE


def default_device() -> torch.device:
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


class TorchGridWorld:
    def __init__(self, episodes: Episodes, seed: int = 0, off_map: str = "random",
                 device: str | torch.device | None = None) -> None:
        """off_map and seed as BatchGridWorld; device None: CUDA when available, else CPU."""
        if off_map not in ("random", "stay"):
            raise ValueError(f"off_map must be 'random' or 'stay' (got {off_map!r})")
        self.off_map = off_map
        self.device = torch.device(device) if device is not None else default_device()
        if getattr(episodes, "mask", None) is not None:
            raise ValueError("TorchGridWorld has no masked fields yet; use BatchGridWorld for episodes with a mask")
        cfg = episodes.cfg
        if not cfg.perfect_detection:
            from .config import ConfigError

            raise ConfigError(f"TorchGridWorld runs the paper's world only (levels = 1, perfect detection); "
                              f"levels = {cfg.levels} needs BatchGridWorld")
        self.cfg, self.episodes = cfg, episodes
        n, r, w, h = len(episodes), cfg.n_targets, cfg.width, cfg.height
        self.n = n
        dev = self.device

        def z(*shape: int, dtype: torch.dtype) -> torch.Tensor:
            return torch.zeros(shape, dtype=dtype, device=dev)

        self._rows = torch.arange(n, device=dev)
        self.rng = np.random.default_rng([seed, 0xAC7])  # the same stream as BatchGridWorld's
        self._deltas = torch.as_tensor(DELTAS, device=dev)
        self._targets0 = torch.as_tensor(episodes.targets, dtype=torch.int64, device=dev)
        self._paths = None if episodes.paths is None else torch.as_tensor(episodes.paths, dtype=torch.int64,
                                                                          device=dev)
        self.agent = torch.as_tensor(episodes.agent, dtype=torch.int64, device=dev).clone()
        self.t = z(n, dtype=torch.int64)
        self.found = z(n, r, dtype=torch.bool)
        self.find_moves = torch.full((n, r), -1, dtype=torch.int64, device=dev)
        ay, ax = self.agent[:, 1], self.agent[:, 0]
        self.visited = z(n, h, w, dtype=torch.bool)
        self.visited[self._rows, ay, ax] = True
        self.met = z(n, h, w, dtype=torch.bool)
        self.trail = z(n, h, w, dtype=torch.float32)
        self.recoveries = z(n, h, w, dtype=torch.float32)
        if cfg.map_variant == "spatiotemporal":
            self.trail[self._rows, ay, ax] = cfg.trail_value
        self._map = z(n, h, w, dtype=torch.float32)
        self._map[self._rows, ay, ax] = VISITED_VALUE
        self.done = z(n, dtype=torch.bool)
        self.replaced = z(n, dtype=torch.int64)
        self._history: list[torch.Tensor] = [self.agent.to(torch.int16)]
        tg = self.targets()
        if bool(((tg[..., 0] == ax[:, None]) & (tg[..., 1] == ay[:, None])).any()):
            raise ValueError("an episode starts with the agent on a target; placement is broken")

    @property
    def n_actions(self) -> int:
        return self.cfg.n_actions

    def targets(self) -> torch.Tensor:
        """Current target cells (n, R, 2)."""
        if self._paths is None:
            return self._targets0
        t = torch.clamp(self.t, max=self._paths.shape[1] - 1)
        return self._paths[self._rows, t]

    def valid_actions(self) -> torch.Tensor:
        x, y = self.agent[:, 0], self.agent[:, 1]
        cols = [y > 0, y < self.cfg.height - 1, x > 0, x < self.cfg.width - 1, torch.ones_like(x, dtype=torch.bool)]
        return torch.stack(cols[: self.n_actions], dim=1)

    def observe(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(views (n, 3, 3, 3) uint8, maps (n, C, h, w) float32), as BatchGridWorld.observe."""
        cfg = self.cfg
        n, w, h = self.n, cfg.width, cfg.height
        x, y = self.agent[:, 0], self.agent[:, 1]
        v = torch.zeros((n, VIEW_CHANNELS, 3, 3), dtype=torch.uint8, device=self.device)
        tg = self.targets()
        dx, dy = tg[..., 0] - x[:, None] + 1, tg[..., 1] - y[:, None] + 1
        near = (dx >= 0) & (dx <= 2) & (dy >= 0) & (dy <= 2)
        ep, _ = torch.nonzero(near, as_tuple=True)
        v[ep, 0, dy[near], dx[near]] = 1
        no = torch.zeros_like(x, dtype=torch.bool)
        off_rows = torch.stack([y == 0, no, y == h - 1], dim=1)
        off_cols = torch.stack([x == 0, no, x == w - 1], dim=1)
        v[:, 1] = (off_rows[:, :, None] | off_cols[:, None, :]).to(torch.uint8)
        v[:, 2, 1, 1] = 1
        if cfg.map_variant == "spatiotemporal":
            m = torch.stack([self.trail, self.recoveries], dim=1)
        else:
            m = self._map.clone()
            m[self._rows, y, x] = AGENT_VALUE
            m = m[:, None]
        return v, m

    def step(self, actions: torch.Tensor | np.ndarray) -> torch.Tensor:
        """One action per episode (ignored where done); targets found (n,), as BatchGridWorld."""
        a = torch.as_tensor(actions, device=self.device).to(torch.int64).clone()
        if tuple(a.shape) != (self.n,):
            raise ValueError(f"expected {self.n} actions, got shape {tuple(a.shape)}")
        if bool(((a < 0) | (a >= self.n_actions)).any()):
            raise ValueError(f"actions must be in 0..{self.n_actions - 1} for this config")
        cfg = self.cfg
        active = ~self.done
        valid = self.valid_actions()
        bad = active & ~valid[self._rows, a]
        n_bad = int(bad.sum())
        if n_bad:
            self.replaced[bad] += 1
            if self.off_map == "random":
                keys = torch.as_tensor(self.rng.random((n_bad, self.n_actions)), device=self.device)
                keys[~valid[bad]] = -1.0
                a[bad] = keys.argmax(dim=1)
        move = active & ~bad if self.off_map == "stay" else active
        self.agent[move] += self._deltas[a[move]]
        self.t[active] += 1
        rows = self._rows[active]
        ay, ax = self.agent[rows, 1], self.agent[rows, 0]
        self.visited[rows, ay, ax] = True
        self._map[rows, ay, ax] = torch.clamp(self._map[rows, ay, ax], min=VISITED_VALUE)
        if cfg.map_variant == "spatiotemporal":
            for grid in (self.trail, self.recoveries):
                g = grid[rows]
                grid[rows] = torch.where(g > 0, g - 1.0, g)
            self.trail[rows, ay, ax] = cfg.trail_value
        tg = self.targets()
        hits = (tg[..., 0] == self.agent[:, None, 0]) & (tg[..., 1] == self.agent[:, None, 1]) & ~self.found
        hits &= active[:, None]
        newly = hits.sum(dim=1)
        got = newly > 0
        if bool(got.any()):
            self.found |= hits
            self.find_moves[hits] = self.t[:, None].expand_as(hits)[hits]
            r, gy, gx = self._rows[got], self.agent[got, 1], self.agent[got, 0]
            self.met[r, gy, gx] = True
            if cfg.map_variant == "memory":
                self._map[r, gy, gx] = MET_VALUE
            self.recoveries[r, gy, gx] = cfg.trail_value
        self.done |= self.found.all(dim=1) | (self.t > cfg.t_e)
        self._history.append(self.agent.to(torch.int16))
        return newly

    def run(self, act, max_steps: int | None = None) -> None:
        """Step until every episode is done; `act(world) -> (n,) actions`."""
        limit = self.cfg.t_e + 1 if max_steps is None else max_steps
        for _ in range(limit):
            if bool(self.done.all()):
                break
            self.step(act(self))

    def trajectories(self) -> torch.Tensor:
        """(n, steps + 1, 2) agent cells over time."""
        return torch.stack(self._history, dim=1)

    @property
    def success(self) -> torch.Tensor:
        return self.found.all(dim=1)
