"""Loop detection and the voting fallback (paper Section V-B; the authors' code settles the
details, see ../shared/reference): a wrapper that gives any policy the same protection.

A queue holds the agent's last 40 positions; a loop is declared when a position occurs
alpha = 3 times in it. The fallback then looks in growing squares (radius 1, 2, ...) around
the agent for unvisited cells (off-map counts as visited); each votes for the direction of
its larger offset (both on an exact diagonal), most votes wins, ties at random. While in the
fallback positions are not queued; once a move lands on an unvisited cell the queue is
cleared and the wrapped policy takes over again. Each trigger counts one loop.
"""

from __future__ import annotations

import numpy as np

from sim.gridworld import Action, Episodes, GridConfig

from .base import Observation, Policy, random_valid


def vote(pos: np.ndarray, visited: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Fallback action for each agent: pos (m, 2), visited (m, h, w) bool -> (m,) actions.

    Agents on a fully visited map get Action.N (the caller replaces it with a valid move).
    """
    m, h, w = visited.shape
    out = np.full(m, Action.N, dtype=np.int64)
    todo = np.arange(m)
    for r in range(1, max(h, w) + 1):
        if todo.size == 0:
            break
        off = np.arange(-r, r + 1)
        dx, dy = np.meshgrid(off, off, indexing="xy")  # (2r+1, 2r+1), rows = dy
        xs = pos[todo, 0, None, None] + dx
        ys = pos[todo, 1, None, None] + dy
        inside = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
        vis = visited[todo[:, None, None], np.clip(ys, 0, h - 1), np.clip(xs, 0, w - 1)]
        free = inside & ~vis  # (k, 2r+1, 2r+1)
        has = free.any(axis=(1, 2))
        if has.any():
            f = free[has]
            ax, ay = np.abs(dx), np.abs(dy)
            horiz = f & (ax >= ay)
            vert = f & (ay >= ax)
            votes = np.stack(
                [
                    (vert & (dy < 0)).sum(axis=(1, 2)),  # f: -y
                    (vert & (dy > 0)).sum(axis=(1, 2)),  # b: +y
                    (horiz & (dx < 0)).sum(axis=(1, 2)),  # l: -x
                    (horiz & (dx > 0)).sum(axis=(1, 2)),  # r: +x
                ],
                axis=1,
            ).astype(np.float64)
            votes += rng.random(votes.shape) * 0.5  # ties at random
            out[todo[has]] = votes.argmax(axis=1)
        todo = todo[~has]
    return out


def queue_step(queue: np.ndarray, qlen: np.ndarray, fallback: np.ndarray, count: np.ndarray, pos: np.ndarray,
               act: np.ndarray, new_cell: np.ndarray, alpha: int) -> None:
    """One step of the paper's loop rule over rows, in place (LoopGuard's episodes, a team's
    agents): a row in the fallback whose move reached an unvisited cell (new_cell) leaves it with
    an empty queue; a row under its policy queues its cell in a ring of queue.shape[1] and enters
    the fallback (count + 1) when that cell occurs alpha times in the ring. queue (rows, window,
    2), qlen / count (rows,) int, fallback (rows,) bool, pos (rows, 2), act / new_cell (rows,)."""
    window = queue.shape[1]
    leave = act & fallback & new_cell
    fallback[leave] = False
    qlen[leave] = 0
    q = act & ~fallback
    queue[np.flatnonzero(q), qlen[q] % window] = pos[q]
    qlen[q] += 1
    filled = np.arange(window)[None, :] < np.minimum(qlen, window)[:, None]
    same = np.all(queue == pos[:, None, :], axis=-1) & filled
    trig = q & (same.sum(axis=1) >= alpha)
    count[trig] += 1
    fallback |= trig


class LoopGuard(Policy):
    """Any policy under loop detection: `LoopGuard(policy)` is itself a Policy, `loops()` gives
    the triggers per episode. Optional by construction: the paper wraps its networks for static
    targets and runs moving targets unwrapped (Section VI-F).

    The visited mask is kept here from positions rather than read from M: for the static maps it
    equals M's cells > 0 (tested), and the spatiotemporal trail forgets cells after 50 moves.
    The wrapped policy is asked every step, in the fallback too, so stateful policies (an LSTM,
    a plan) keep their state in step with the world."""

    def __init__(self, policy: Policy, alpha: int = 3, window: int = 40) -> None:
        if alpha < 2 or window < alpha:
            raise ValueError(f"need 2 <= alpha <= window (got alpha={alpha}, window={window})")
        self.inner, self.alpha, self.window = policy, alpha, window
        #: decide a single episode through _act_one (False: the array path, for tests)
        self.scalar_one = True
        self.name = policy.name
        self.needs_truth = policy.needs_truth

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        self.inner.reset(cfg, n, seed, episodes)
        self.rng = np.random.default_rng([seed, 0x100F])
        self.queue = np.full((n, self.window, 2), -1, dtype=np.int64)
        self.qlen = np.zeros(n, dtype=np.int64)
        self.visited = np.zeros((n, cfg.height, cfg.width), dtype=bool)
        self.fallback = np.zeros(n, dtype=bool)
        self.count = np.zeros(n, dtype=np.int64)
        self.rows = np.arange(n)
        #: batch 1: how often each cell occurs in the queue's filled part (see _act_one)
        self._counts: dict[tuple[int, int], int] = {}
        self._masked = False

    def _act_one(self, obs: Observation, a: np.ndarray) -> np.ndarray:
        """act() for a single episode (the flight decides at batch 1): the same state changes
        and actions (tested against the array path), with Python scalars for the cell and a
        running count of each queued cell instead of scanning the queue: at batch 1 the
        guard's cost is numpy's per-call overhead, ~25 calls per decision."""
        if not bool(obs.active[0]):
            return a
        x, y = (int(v) for v in obs.positions[0])
        new_cell = not self.visited[0, y, x]
        self.visited[0, y, x] = True
        if self.fallback[0] and new_cell:  # leaving the fallback: the queue starts empty
            self.fallback[0] = False
            self.qlen[0] = 0
            self._counts.clear()
        if not self.fallback[0]:
            n = int(self.qlen[0])
            slot = n % self.window
            if n >= self.window:  # the ring is full: its oldest entry is overwritten
                old = (int(self.queue[0, slot, 0]), int(self.queue[0, slot, 1]))
                self._counts[old] -= 1
            self.queue[0, slot] = (x, y)
            self.qlen[0] = n + 1
            same = self._counts.get((x, y), 0) + 1
            self._counts[(x, y)] = same
            if same >= self.alpha:
                self.count[0] += 1
                self.fallback[0] = True
        if self.fallback[0]:
            a[:] = vote(obs.positions[:1], self.visited, self.rng)
            if a[0] == Action.N:  # nothing left unvisited: any valid move
                a[:] = random_valid(obs.valid[:1, :4], self.rng)
        return a

    def loops(self) -> np.ndarray:
        return self.count.copy()

    def act(self, obs: Observation) -> np.ndarray:
        a = np.asarray(self.inner.act(obs), dtype=np.int64).copy()
        if obs.mask is not None and not self._masked:
            # masked cells count as visited, like off-map ones: the vote never heads for them
            self._masked = True
            self.visited |= ~np.asarray(obs.mask, bool)
        if self.scalar_one and len(a) == 1:
            return self._act_one(obs, a)
        act, pos, rows = obs.active, obs.positions, self.rows
        new_cell = ~self.visited[rows, pos[:, 1], pos[:, 0]]
        self.visited[rows[act], pos[act, 1], pos[act, 0]] = True
        queue_step(self.queue, self.qlen, self.fallback, self.count, pos, act, new_cell, self.alpha)
        fb = act & self.fallback
        if fb.any():
            a[fb] = vote(pos[fb], self.visited[fb], self.rng)
            stuck = fb & (a == Action.N)  # nothing left unvisited: any valid move
            if stuck.any():
                a[stuck] = random_valid(obs.valid[stuck, :4], self.rng)
        return a
