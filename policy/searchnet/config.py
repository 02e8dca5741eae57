"""The network's shape, one frozen validated data class: what a checkpoint must record to be
rebuilt. Nothing here depends on the field size, so one checkpoint runs on any grid."""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class SearchNetConfig:
    #: belief planes per cell (policy.belief.BELIEF_CHANNELS when built for the actor)
    in_channels: int
    #: extra planes only the critic sees (the truth: where the unfound targets are now)
    privileged_channels: int = 0
    conv1: int = 16
    conv2: int = 32
    hidden: int = 64
    #: side of the agent-centred window whose first-layer features go to the head as they are
    local: int = 5
    #: f, b, l, r, stay; static worlds mask the stay
    n_actions: int = 5

    def __post_init__(self) -> None:
        for name in ("in_channels", "conv1", "conv2", "hidden", "n_actions"):
            if getattr(self, name) < 1:
                raise ValueError(f"SearchNetConfig.{name} must be >= 1 (got {getattr(self, name)})")
        if self.privileged_channels < 0:
            raise ValueError(f"SearchNetConfig.privileged_channels must be >= 0 (got {self.privileged_channels})")
        if self.local < 1 or self.local % 2 == 0:
            raise ValueError(f"SearchNetConfig.local must be a positive odd window side (got {self.local})")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> SearchNetConfig:
        unknown = sorted(set(d) - set(cls.__dataclass_fields__))
        if unknown:
            raise ValueError(f"unknown SearchNetConfig field(s): {unknown}")
        return cls(**d)
