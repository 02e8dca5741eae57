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
    #: f, b, l, r, stay; static worlds mask the stay; 7 with altitude levels (+ climb, descend)
    n_actions: int = 5
    #: one-hot planes of the level flown, L_max of them (0: no level input, the networks from
    #: before altitude levels): a network with L_max = 3 serves every field with levels 1..3
    #: (climb and descend are masked where the field has no level to go to)
    level_planes: int = 0
    #: planes of the teammates (issue 29, policy.searchnet.team.teammates_planes): 1: a plane
    #: with 1 on every other agent's cell; 2: also 1 on the cells some other agent is strictly
    #: nearer (Manhattan: the team's regions); all 0 for a lone agent. 0: none, the
    #: single-agent networks from before teams
    team_planes: int = 0

    def __post_init__(self) -> None:
        for name in ("in_channels", "conv1", "conv2", "hidden", "n_actions"):
            if getattr(self, name) < 1:
                raise ValueError(f"SearchNetConfig.{name} must be >= 1 (got {getattr(self, name)})")
        if self.privileged_channels < 0:
            raise ValueError(f"SearchNetConfig.privileged_channels must be >= 0 (got {self.privileged_channels})")
        if self.level_planes < 0:
            raise ValueError(f"SearchNetConfig.level_planes must be >= 0 (got {self.level_planes})")
        if self.team_planes not in (0, 1, 2):
            raise ValueError(f"SearchNetConfig.team_planes must be 0, 1 or 2 (got {self.team_planes})")
        if self.level_planes and self.n_actions < 7:
            raise ValueError(f"SearchNetConfig: level planes need the 7 actions with climb and descend "
                             f"(got n_actions {self.n_actions})")
        if self.local < 1 or self.local % 2 == 0:
            raise ValueError(f"SearchNetConfig.local must be a positive odd window side (got {self.local})")

    def to_dict(self) -> dict:
        """level_planes and team_planes appear only where they are used, so a network without
        levels or teammates writes the same document as before they existed."""
        d = asdict(self)
        if not self.level_planes:
            d.pop("level_planes")
        if not self.team_planes:
            d.pop("team_planes")
        return d

    @property
    def field_planes(self) -> int:
        """Planes per field cell before the egocentric crop adds its own: belief, level,
        teammates, truth."""
        return self.in_channels + self.level_planes + self.team_planes + self.privileged_channels

    @classmethod
    def from_dict(cls, d: dict) -> SearchNetConfig:
        unknown = sorted(set(d) - set(cls.__dataclass_fields__))
        if unknown:
            raise ValueError(f"unknown SearchNetConfig field(s): {unknown}")
        return cls(**d)
