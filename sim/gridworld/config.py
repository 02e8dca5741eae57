"""Episode configuration: one validated data class, built by the CLI, read by everything."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from .detection import DetectionTable

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
    #: altitude levels 1..levels the agent can fly (docs/altitude.md); 1 = the paper's world
    levels: int = 1
    #: what each level sees (sim.gridworld.detection.DetectionTable); None: perfect at level 1,
    #: the measured default table for levels > 1 (a ConfigError until it is shipped)
    detection: DetectionTable | None = None
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
        if not 1 <= self.levels <= 3:
            raise ConfigError(f"levels must be in 1..3 (got {self.levels})")
        if self.detection is not None or self.levels > 1:
            from .detection import DetectionTable, default_table

            det = self.detection
            if isinstance(det, dict):
                det = DetectionTable.from_dict(det)
            elif det is None:
                det = default_table()
            if not isinstance(det, DetectionTable):
                raise ConfigError(f"detection must be a DetectionTable or its dict (got {type(det).__name__})")
            if det.levels < self.levels:
                raise ConfigError(f"the detection table has {det.levels} level(s); levels = {self.levels} needs "
                                  f"{self.levels}")
            object.__setattr__(self, "detection", det)
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
        """4 for static targets, 5 (with stay) for moving ones, as in the paper; 7 (with climb
        and descend, Action values 5 and 6) where levels > 1."""
        if self.levels > 1:
            return 7
        return 5 if self.moving else 4

    @property
    def view_radius(self) -> int:
        """Radius of the view window at the highest level (1: the paper's 3 x 3)."""
        return self.levels

    @property
    def perfect_detection(self) -> bool:
        """Level 1 only and it sees perfectly: the paper's world, on today's code paths."""
        return self.levels == 1 and (self.detection is None or self.detection.perfect_at(1))

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
        """Plain JSON values. levels and detection appear only where they are not the paper's
        world (levels 1, no table), so every document written before them reads the same."""
        d = asdict(self)
        d.pop("extra", None)
        d["gaussian_mean"] = list(self.gaussian_mean)
        if self.detection is None:
            d.pop("detection", None)
        else:
            d["detection"] = self.detection.to_dict()
        if self.levels == 1 and self.detection is None:
            d.pop("levels", None)
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
