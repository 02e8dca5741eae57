"""Every DRQN hyper-parameter in one place; the defaults are the authors' values (Hausknecht &
Stone's DRQN as the authors ran it, see ../shared/reference/authors-code-facts.md)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

#: conv layers before the last one: (out channels, kernel, stride), valid padding
DEFAULT_CONV: tuple[tuple[int, int, int], ...] = ((32, 8, 4), (64, 4, 2), (64, 3, 1))


class DrqnConfigError(ValueError):
    """A DRQN config that cannot train or build a network."""


def conv_output_size(size: int, conv: tuple[tuple[int, int, int], ...]) -> int:
    """Spatial size after the valid-padding conv stack (what the last conv must span)."""
    for _, k, s in conv:
        size = (size - k) // s + 1
    return size


@dataclass(frozen=True)
class DrqnConfig:
    # network: the 3x3 view rendered as an RGB image of input_size x input_size pixels
    input_size: int = 84  # 42 is the CI-speed option (14 px per cell, last conv 1x1)
    conv: tuple[tuple[int, int, int], ...] = DEFAULT_CONV
    hidden: int = 512  # last conv channels = LSTM width; the dueling heads split it in halves
    n_actions: int = 4
    # learning
    lr: float = 1e-4
    gamma: float = 0.99
    tau: float = 0.001  # soft target update, applied with every training update
    update_every: int = 5  # environment steps per training update
    replay_episodes: int = 1000
    batch_sequences: int = 4
    trace_length: int = 8  # the first half of each sequence only warms the LSTM up (no loss)
    # exploration
    random_steps: int = 10_000  # pure random steps before training starts
    anneal_steps: int = 10_000  # epsilon eps_start -> eps_end linearly after that
    eps_start: float = 1.0
    eps_end: float = 0.1
    eps_test: float = 0.01
    # run
    episodes: int = 20_000
    n_envs: int = 16  # episodes stepped in lock-step
    scale: float = 1.0  # multiplies episodes, random_steps and anneal_steps (small runs)
    threads: int = 1  # torch intra-op threads (shared CPU boxes)
    time_limit_s: float | None = None  # stop early (and say so in the checkpoint)
    checkpoint_every: int = 500  # episodes between intermediate checkpoints (0: end only)

    def __post_init__(self) -> None:
        object.__setattr__(self, "conv", tuple(tuple(int(v) for v in c) for c in self.conv))
        if self.input_size % 3:
            raise DrqnConfigError(f"input_size must be a multiple of 3 (3 view cells), got {self.input_size}")
        if conv_output_size(self.input_size, self.conv) < 1:
            raise DrqnConfigError(f"input_size {self.input_size} is too small for conv stack {self.conv}")
        if self.hidden < 2 or self.hidden % 2:
            raise DrqnConfigError(f"hidden must be even and >= 2 (dueling halves), got {self.hidden}")
        if self.n_actions not in (4, 5):
            raise DrqnConfigError(f"n_actions must be 4 or 5, got {self.n_actions}")
        if self.trace_length < 2 or self.trace_length % 2:
            raise DrqnConfigError(f"trace_length must be even and >= 2, got {self.trace_length}")
        for name in ("update_every", "replay_episodes", "batch_sequences", "episodes", "n_envs", "threads"):
            if getattr(self, name) < 1:
                raise DrqnConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("random_steps", "anneal_steps", "checkpoint_every"):
            if getattr(self, name) < 0:
                raise DrqnConfigError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not (0 < self.gamma <= 1 and 0 < self.tau <= 1 and self.lr > 0 and self.scale > 0):
            raise DrqnConfigError("need 0 < gamma <= 1, 0 < tau <= 1, lr > 0 and scale > 0")
        for name in ("eps_start", "eps_end", "eps_test"):
            if not 0 <= getattr(self, name) <= 1:
                raise DrqnConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")

    @property
    def total_episodes(self) -> int:
        return max(1, round(self.episodes * self.scale))

    @property
    def total_random_steps(self) -> int:
        return round(self.random_steps * self.scale)

    @property
    def total_anneal_steps(self) -> int:
        return round(self.anneal_steps * self.scale)

    def epsilon(self, step: int) -> float:
        """Exploration rate after `step` environment steps."""
        s = step - self.total_random_steps
        if s < 0:
            return self.eps_start
        if self.total_anneal_steps == 0:
            return self.eps_end
        frac = min(1.0, s / self.total_anneal_steps)
        return self.eps_start + frac * (self.eps_end - self.eps_start)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["conv"] = [list(c) for c in self.conv]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> DrqnConfig:
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise DrqnConfigError(f"unknown DrqnConfig field(s): {unknown}")
        d = dict(d)
        if "conv" in d:
            d["conv"] = tuple(tuple(c) for c in d["conv"])
        return cls(**d)

    @classmethod
    def small(cls, **overrides: Any) -> DrqnConfig:
        """The CI-speed variant: 42 px input, 1000 episodes' worth of schedule (scale 0.05)."""
        base: dict[str, Any] = {"input_size": 42, "scale": 0.05}
        base.update(overrides)
        return cls(**base)
