"""Episode replay for recurrent Q-learning: whole episodes are stored, fixed-length traces
are sampled from random episodes at random starts, and the LSTM starts each trace from zero.

The first half of every trace only warms the LSTM up: its loss is masked (Lample & Chaplot's
trick, used by the reference DRQN). Episodes shorter than a trace are padded at the end, and
the padding is masked too.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StoredEpisode:
    frames: np.ndarray  # (L + 1, 3, 3, 3) uint8 compact RGB frames, before each move and after the last
    actions: np.ndarray  # (L,) int64
    rewards: np.ndarray  # (L,) float32
    terminal: np.ndarray  # (L,) bool: no bootstrapping past this step (all targets found)

    def __post_init__(self) -> None:
        n = len(self.actions)
        if n < 1 or self.frames.shape[0] != n + 1 or len(self.rewards) != n or len(self.terminal) != n:
            raise ValueError(
                f"inconsistent episode: {self.frames.shape[0]} frames, {n} actions, "
                f"{len(self.rewards)} rewards, {len(self.terminal)} terminal flags"
            )


@dataclass(frozen=True)
class TraceBatch:
    frames: np.ndarray  # (B, T + 1, 3, 3, 3) uint8: states s_0 .. s_T of each trace
    actions: np.ndarray  # (B, T) int64
    rewards: np.ndarray  # (B, T) float32
    terminal: np.ndarray  # (B, T) bool
    mask: np.ndarray  # (B, T) float32: 1 where the step contributes to the loss


def loss_mask(lengths: np.ndarray, trace_length: int) -> np.ndarray:
    """(B, T) mask: zero for the warm-up half and for padding past each trace's real length."""
    steps = np.arange(trace_length)
    return ((steps >= trace_length // 2) & (steps < np.asarray(lengths)[:, None])).astype(np.float32)


class EpisodeReplay:
    """The last `capacity` episodes (oldest dropped first)."""

    def __init__(self, capacity: int, trace_length: int, seed: int) -> None:
        if capacity < 1 or trace_length < 2:
            raise ValueError(f"need capacity >= 1 and trace_length >= 2 (got {capacity}, {trace_length})")
        self.capacity, self.trace_length = capacity, trace_length
        self.episodes: deque[StoredEpisode] = deque(maxlen=capacity)
        self.rng = np.random.default_rng([seed, 0x4E91])

    def __len__(self) -> int:
        return len(self.episodes)

    def add(self, episode: StoredEpisode) -> None:
        self.episodes.append(episode)

    def sample(self, batch: int) -> TraceBatch:
        if not self.episodes:
            raise ValueError("cannot sample from an empty replay buffer")
        t = self.trace_length
        frames = np.zeros((batch, t + 1, 3, 3, 3), dtype=np.uint8)
        actions = np.zeros((batch, t), dtype=np.int64)
        rewards = np.zeros((batch, t), dtype=np.float32)
        terminal = np.zeros((batch, t), dtype=bool)
        lengths = np.zeros(batch, dtype=np.int64)
        picks = self.rng.integers(0, len(self.episodes), size=batch)
        for i, k in enumerate(picks):  # batch is 4: per-trace slicing, not a hot loop
            ep = self.episodes[int(k)]
            n = len(ep.actions)
            s = int(self.rng.integers(0, n - t + 1)) if n >= t else 0
            m = min(t, n)
            frames[i, : m + 1] = ep.frames[s : s + m + 1]
            actions[i, :m] = ep.actions[s : s + m]
            rewards[i, :m] = ep.rewards[s : s + m]
            terminal[i, :m] = ep.terminal[s : s + m]
            lengths[i] = m
        return TraceBatch(frames, actions, rewards, terminal, loss_mask(lengths, t))
