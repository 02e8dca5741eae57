"""Episode configuration: one validated data class, built by the CLI, read by everything."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Literal

Distribution = Literal["random", "fixed", "equidistant", "gaussian"]
Motion = Literal["static", "random_walk", "herd"]
MapVariant = Literal["spatial", "memory", "spatiotemporal"]

DISTRIBUTIONS: tuple[str, ...] = ("random", "fixed", "equidistant", "gaussian")
MOTIONS: tuple[str, ...] = ("static", "random_walk", "herd")
MAP_VARIANTS: tuple[str, ...] = ("spatial", "memory", "spatiotemporal")


class ConfigError(ValueError):
    """A configuration value that cannot work; the message names the field and the fix."""


@dataclass(frozen=True)
class GridConfig:
    """The paper's grid world. Defaults are the paper's base case (Section VI)."""

    width: int = 10
    height: int = 10
    n_targets: int = 5
    distribution: Distribution = "random"
    motion: Motion = "static"
    #: spatial: visited=1, agent=10. memory (+M): also met targets=5. spatiotemporal: 2 decaying channels.
    map_variant: MapVariant = "spatial"
    t_e: int = 300
    #: targets move on steps where t % target_period == 0 (the paper's 1/3 speed).
    target_period: int = 3
    gaussian_mean: tuple[float, float] = (3.0, 5.0)
    gaussian_sd: float = 1.0
    grid_spacing: int = 2
    herd_deviation: float = 0.1
    #: spatiotemporal trail value written at the current cell; decays by 1 per step.
    trail_value: int = 50
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.width < 2 or self.height < 2:
            raise ConfigError(f"width and height must be >= 2 (got {self.width} x {self.height})")
        if not 1 <= self.n_targets <= self.width * self.height - 1:
            raise ConfigError(
                f"n_targets must be in 1..{self.width * self.height - 1} for a "
                f"{self.width} x {self.height} grid (got {self.n_targets})"
            )
        if self.distribution not in DISTRIBUTIONS:
            raise ConfigError(f"distribution must be one of {DISTRIBUTIONS} (got {self.distribution!r})")
        if self.motion not in MOTIONS:
            raise ConfigError(f"motion must be one of {MOTIONS} (got {self.motion!r})")
        if self.map_variant not in MAP_VARIANTS:
            raise ConfigError(f"map_variant must be one of {MAP_VARIANTS} (got {self.map_variant!r})")
        if self.t_e < 1:
            raise ConfigError(f"t_e must be >= 1 (got {self.t_e})")
        if self.target_period < 1:
            raise ConfigError(f"target_period must be >= 1 (got {self.target_period})")
        if self.gaussian_sd <= 0:
            raise ConfigError(f"gaussian_sd must be > 0 (got {self.gaussian_sd})")
        if self.grid_spacing < 1:
            raise ConfigError(f"grid_spacing must be >= 1 (got {self.grid_spacing})")
        if not 0.0 <= self.herd_deviation <= 1.0:
            raise ConfigError(f"herd_deviation must be in [0, 1] (got {self.herd_deviation})")
        if self.distribution in ("fixed", "equidistant"):
            cols, rows = self.lattice_shape
            span_x, span_y = (cols - 1) * self.grid_spacing, (rows - 1) * self.grid_spacing
            if span_x >= self.width or span_y >= self.height:
                raise ConfigError(
                    f"{self.n_targets} targets at spacing {self.grid_spacing} need a lattice "
                    f"{span_x + 1} x {span_y + 1}, larger than the {self.width} x {self.height} grid"
                )

    @property
    def moving(self) -> bool:
        return self.motion != "static"

    @property
    def n_actions(self) -> int:
        """4 for static targets, 5 (with stay) for moving ones, as in the paper."""
        return 5 if self.moving else 4

    @property
    def map_channels(self) -> int:
        return 2 if self.map_variant == "spatiotemporal" else 1

    @property
    def lattice_shape(self) -> tuple[int, int]:
        """(columns, rows) of the target lattice used by fixed and equidistant placement."""
        cols = 1
        while cols * cols < self.n_targets:
            cols += 1
        rows = -(-self.n_targets // cols)
        return cols, rows

    def to_dict(self) -> dict:
        d = asdict(self)
        d.pop("extra", None)
        d["gaussian_mean"] = list(self.gaussian_mean)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> GridConfig:
        known = {k: v for k, v in d.items() if k in cls.__dataclass_fields__ and k != "extra"}
        unknown = sorted(set(d) - set(known) - {"extra"})
        if unknown:
            raise ConfigError(f"unknown GridConfig field(s): {unknown}")
        if "gaussian_mean" in known:
            known["gaussian_mean"] = tuple(known["gaussian_mean"])
        return cls(**known)
