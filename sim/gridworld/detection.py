"""Altitude levels: what the camera sees from each level (the detection table) and how long
a move takes (the flight model). docs/altitude.md explains the model.

Level l (1..L) sees the (2 r(l) + 1)^2 cells around the nadir cell, r(l) = l. Each target in
view is detected with probability p_d(l, ring), ring = the Chebyshev distance in cells from
the nadir cell (0..r(l)); each empty cell in view raises a false alarm with probability
false_alarm_per_cell(l). Recovery (a target counts as found) stays what the paper says: the
agent at the target's cell at level 1.

The table is a JSON file:

    {"format": "uavsearch.detection/1", "levels": [1, 2, 3], "height_m": [3.5, 5.83, 8.17],
     "view_radius": [1, 2, 3], "p_detect": [[p0, p1], [p0, p1, p2], [p0, p1, p2, p3]],
     "false_alarm_per_cell": [f1, f2, f3], "provenance": {...}}

The default one is measured on the SITL's camera (`uavsearch detector-curve`) and shipped as
package data at sim/gridworld/data/detection.json; until it is, levels > 1 need a table given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from provenance import InputFileError, read_json

from .config import ConfigError

FORMAT = "uavsearch.detection/1"
MAX_LEVELS = 3
#: the measured default table (package data)
DEFAULT_TABLE = Path(__file__).resolve().parent / "data" / "detection.json"


def view_radius(level: int) -> int:
    """r(l) = l: level 1 sees 3 x 3 cells (the paper's view), 2 sees 5 x 5, 3 sees 7 x 7."""
    return int(level)


def level_height_m(level: int, base_m: float = 3.5) -> float:
    """h(l) = base * (2 r(l) + 1) / 3: the footprint grows with the height, so the same margin
    of the 100-degree camera's footprint around the (2r+1)^2 cells as the 3 x 3 at 3.5 m."""
    return base_m * (2 * view_radius(level) + 1) / 3.0


@dataclass(frozen=True)
class DetectionTable:
    """p_d(level, ring) and the false-alarm rate per level. Frozen, validated, hashable."""

    p_detect: tuple[tuple[float, ...], ...]
    false_alarm_per_cell: tuple[float, ...]
    height_m: tuple[float, ...] = ()
    provenance: dict = field(default_factory=dict, compare=False, hash=False, repr=False)

    def __post_init__(self) -> None:
        p = tuple(tuple(float(v) for v in row) for row in self.p_detect)
        fa = tuple(float(v) for v in self.false_alarm_per_cell)
        hm = tuple(float(v) for v in self.height_m) or tuple(level_height_m(i + 1) for i in range(len(p)))
        object.__setattr__(self, "p_detect", p)
        object.__setattr__(self, "false_alarm_per_cell", fa)
        object.__setattr__(self, "height_m", hm)
        if not 1 <= len(p) <= MAX_LEVELS:
            raise ConfigError(f"detection table: p_detect needs 1..{MAX_LEVELS} levels (got {len(p)})")
        for i, row in enumerate(p):
            lvl = i + 1
            if len(row) != view_radius(lvl) + 1:
                raise ConfigError(f"detection table: p_detect[{i}] (level {lvl}) needs {view_radius(lvl) + 1} "
                                  f"rings 0..{view_radius(lvl)} (got {len(row)})")
            if not all(math.isfinite(v) and 0.0 <= v <= 1.0 for v in row):
                raise ConfigError(f"detection table: p_detect[{i}] must be probabilities in [0, 1] (got {row})")
        if len(fa) != len(p):
            raise ConfigError(f"detection table: false_alarm_per_cell needs one rate per level ({len(p)}, got {len(fa)})")
        if not all(math.isfinite(v) and 0.0 <= v < 1.0 for v in fa):
            raise ConfigError(f"detection table: false_alarm_per_cell must be in [0, 1) (got {fa})")
        if len(hm) != len(p) or not all(math.isfinite(v) and v > 0 for v in hm):
            raise ConfigError(f"detection table: height_m needs one positive height per level (got {hm})")

    @property
    def levels(self) -> int:
        return len(self.p_detect)

    def perfect_at(self, level: int) -> bool:
        """Level `level` sees every target in view and raises no false alarm (today's world)."""
        return all(v == 1.0 for v in self.p_detect[level - 1]) and self.false_alarm_per_cell[level - 1] == 0.0

    def ring_table(self, levels: int) -> tuple[list[list[float]], list[float]]:
        """(p[l - 1][ring] for ring 0..r(levels), padded with 0 beyond r(l); false alarms)."""
        rmax = view_radius(levels)
        rows = [list(self.p_detect[i]) + [0.0] * (rmax - view_radius(i + 1)) for i in range(levels)]
        return rows, list(self.false_alarm_per_cell[:levels])

    def to_dict(self) -> dict[str, Any]:
        n = self.levels
        return {
            "format": FORMAT, "levels": list(range(1, n + 1)), "height_m": list(self.height_m),
            "view_radius": [view_radius(i + 1) for i in range(n)],
            "p_detect": [list(r) for r in self.p_detect],
            "false_alarm_per_cell": list(self.false_alarm_per_cell), "provenance": dict(self.provenance),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str = "detection table") -> DetectionTable:
        if not isinstance(d, dict):
            raise ConfigError(f"{source}: expected a JSON object (got {type(d).__name__})")
        if d.get("format") != FORMAT:
            raise ConfigError(f"{source}: format must be {FORMAT!r} (got {d.get('format')!r})")
        for k in ("p_detect", "false_alarm_per_cell"):
            if k not in d:
                raise ConfigError(f"{source}: missing {k!r}")
        n = len(d["p_detect"])
        if "levels" in d and list(d["levels"]) != list(range(1, n + 1)):
            raise ConfigError(f"{source}: levels must be {list(range(1, n + 1))} (got {d['levels']})")
        if "view_radius" in d and list(d["view_radius"]) != [view_radius(i + 1) for i in range(n)]:
            raise ConfigError(f"{source}: view_radius must be {[view_radius(i + 1) for i in range(n)]} "
                              f"(got {d['view_radius']})")
        try:
            return cls(tuple(tuple(r) for r in d["p_detect"]), tuple(d["false_alarm_per_cell"]),
                       tuple(d.get("height_m", ())), dict(d.get("provenance", {})))
        except ConfigError as e:
            raise ConfigError(f"{source}: {e}") from e
        except (TypeError, ValueError) as e:  # a value that is not a number, a row not a list
            raise ConfigError(f"{source}: {e}") from e

    @classmethod
    def load(cls, path: str | Path) -> DetectionTable:
        path = Path(path)
        if not path.is_file():
            raise ConfigError(f"no detection table at {path}")
        try:
            d = read_json(path, "detection table")
        except InputFileError as e:
            raise ConfigError(str(e)) from None
        return cls.from_dict(d, source=str(path))

    @classmethod
    def perfect(cls, levels: int = 1) -> DetectionTable:
        """Every target in view seen, no false alarm: level 1 of it is today's world."""
        return cls(tuple((1.0,) * (view_radius(i + 1) + 1) for i in range(levels)), (0.0,) * levels)


def default_table() -> DetectionTable:
    """The measured table shipped with the package; a clear error until it is."""
    if not DEFAULT_TABLE.is_file():
        raise ConfigError(
            f"levels > 1 need a detection table: the measured default {DEFAULT_TABLE} does not exist yet "
            f"(`uavsearch detector-curve` writes it); give one with --detection TABLE.json "
            f"(GridConfig(detection=DetectionTable.load(path)))")
    return DetectionTable.load(DEFAULT_TABLE)


@dataclass(frozen=True)
class FlightModel:
    """How long a move takes, for the flight-time report: one cell horizontally at
    horizontal_mps (a stay hovers as long), one level vertically at vertical_mps between the
    levels' heights h(l) (level_height_m)."""

    cell_m: float = 2.0
    horizontal_mps: float = 2.0
    vertical_mps: float = 1.0
    base_height_m: float = 3.5

    def __post_init__(self) -> None:
        for k in ("cell_m", "horizontal_mps", "vertical_mps", "base_height_m"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"FlightModel.{k} must be > 0 (got {v})")

    @property
    def move_s(self) -> float:
        """Seconds per horizontal move (and per stay)."""
        return self.cell_m / self.horizontal_mps

    def climb_s(self, level_from: int, level_to: int) -> float:
        """Seconds to change height from one level to another."""
        dh = abs(level_height_m(level_to, self.base_height_m) - level_height_m(level_from, self.base_height_m))
        return dh / self.vertical_mps

    def step_seconds(self, levels: int):
        """(levels + 1, levels + 1) table: seconds of a move from level a to level b (row a,
        column b; level a == b: a horizontal move or a stay)."""
        import numpy as np

        t = np.full((levels + 1, levels + 1), self.move_s)
        for a in range(1, levels + 1):
            for b in range(1, levels + 1):
                if a != b:
                    t[a, b] = self.climb_s(a, b)
        return t


FLIGHT = FlightModel()
