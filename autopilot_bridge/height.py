"""The height the search flies at: the altitude level commanded, and the camera's height as flown.

Its own part of the service because three others read it each decision: the pilot commands the
level's height (over home, as the single search height always was), and the detector, the
registration and the found-target memory scale every blob by the camera's height. With altitude
levels (GridConfig.levels > 1, docs/altitude.md) a level l is flown at h(l) over home
(`sim.gridworld.level_height_m`, the grid world's own definition) and the camera's height is
read from the autopilot's estimate at the frame's instant (its barometer/EKF height, not the
commanded one: the footprint, pixels per metre and blob sizes follow what is flown). With one
level nothing changes: the camera height is the commanded one, `SearchSpec.camera_height()`,
exactly as before (today's flights to the bit).
"""

from __future__ import annotations

from sim.gridworld import level_height_m

from .detector import CAMERA_BELOW_M
from .search_data import SearchSpec
from .telemetry import TelemetryIntake


class FlownHeight:
    """The level flown (1 = the paper's height) and the camera's height over the field."""

    def __init__(self, spec: SearchSpec, intake: TelemetryIntake) -> None:
        self.spec, self.intake = spec, intake
        self.levels = spec.grid.levels
        self.level = 1
        #: the camera's height over the field (m) the current frame is read at
        self.camera_m = spec.camera_height()

    def altitude_m(self, level: int | None = None) -> float:
        """The search height over home (m) of a level (default: the one flown): the spec's
        altitude at level 1 (3.5 m), h(l) with that base above it."""
        lv = self.level if level is None else int(level)
        if not 1 <= lv <= self.levels:
            raise ValueError(f"level must be in 1..{self.levels} (got {lv})")
        return self.spec.altitude_m if lv == 1 else level_height_m(lv, self.spec.altitude_m)

    def set_level(self, level: int) -> None:
        """Fly this level from now on (the pilot's next setpoint carries its height)."""
        self.altitude_m(level)  # validated
        self.level = int(level)

    def read(self, t: float, home_down: float) -> float:
        """The camera's height at simulated time t (frames and blobs read at it): with levels,
        the autopilot's height over home then (home_down: home's height in its local frame)
        less CAMERA_BELOW_M, the commanded height where no estimate is at hand; one level:
        the commanded height, as always."""
        if self.levels == 1:
            self.camera_m = self.spec.camera_height()
            return self.camera_m
        d = self.intake.down_at(t)
        flown = home_down - d[0] if d is not None else self.altitude_m()
        self.camera_m = max(flown - CAMERA_BELOW_M, 0.5)
        return self.camera_m


def footprint_margin_m(level: int, altitude_m: float = 3.5, fov_deg: float = 100.0, cell_m: float = 2.0) -> float:
    """How far (m) the camera's frame reaches beyond the (2 l + 1)^2 cells level l sees, flown
    at its height h(l) over a flat field (negative: the frame does not cover the window). 100
    degrees: 1.1 m at level 1 (3.5 m), 1.9 m at level 2 (5.83 m), 2.7 m at level 3 (8.17 m)."""
    from .edges import half_footprint_m

    h = altitude_m if level == 1 else level_height_m(level, altitude_m)
    return half_footprint_m(h - CAMERA_BELOW_M, fov_deg) - (level + 0.5) * cell_m
