"""Grid cell <-> local NED. The only place this mapping is written; everything else calls it.

Cell (x, y) sits at north = -y * cell, east = x * cell from the field origin (cell (0, 0)),
so f (-y) flies north and r (+x) flies east: today's north-aligned grid. `GridFrame` is the
same mapping for a grid at any heading and origin (a real field's, `sim.field`): it rotates
and shifts these functions' result, and at heading 0, origin (0, 0) returns it unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

DEFAULT_CELL_M = 2.0


def cell_to_ned(cell: np.ndarray | tuple[float, float], cell_m: float = DEFAULT_CELL_M) -> np.ndarray:
    """(…, 2) cells (x, y) -> (…, 2) metres (north, east). Fractional cells are allowed."""
    c = np.asarray(cell, dtype=np.float64)
    return np.stack([-c[..., 1] * cell_m, c[..., 0] * cell_m], axis=-1)


def ned_to_cell(ne: np.ndarray | tuple[float, float], cell_m: float = DEFAULT_CELL_M) -> np.ndarray:
    """(…, 2) metres (north, east) -> (…, 2) fractional cells (x, y); round to get a cell."""
    p = np.asarray(ne, dtype=np.float64)
    return np.stack([p[..., 1] / cell_m, -p[..., 0] / cell_m], axis=-1)


def nearest_cell(ne: np.ndarray | tuple[float, float], cell_m: float = DEFAULT_CELL_M) -> np.ndarray:
    """The integer cell a NED position falls in (cells are centred on their grid point)."""
    return np.rint(ned_to_cell(ne, cell_m)).astype(np.int64)


@dataclass(frozen=True)
class GridFrame:
    """Cell <-> local NED for a grid at any heading and origin: the one mapping every part uses
    (the SITL's field, its targets and truth, the companion's setpoints and registration).

    `heading_deg` is the bearing (degrees clockwise from true north) of the grid's -y axis, the
    direction the move f flies; +x (the move r) points at heading + 90. The grid's own frame,
    (ahead, right) metres, is today's north-aligned mapping above (`cell_to_ned`); this class
    only rotates it by the heading and shifts it by `origin_ne` (cell (0, 0)'s centre in the NED
    frame). At heading 0 and origin (0, 0) every method returns the plain functions' arrays
    unchanged, bit for bit (no multiplication by cos 0 = 1 is even done). Vectorised over any
    leading shape. About the origin: north = -(y cos h + x sin h) * cell_m,
    east = (x cos h - y sin h) * cell_m."""

    heading_deg: float = 0.0
    cell_m: float = DEFAULT_CELL_M
    #: cell (0, 0)'s centre in the local NED frame (north, east), metres
    origin_ne: tuple[float, float] = (0.0, 0.0)
    _cs: tuple[float, float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not math.isfinite(self.heading_deg):
            raise ValueError(f"grid heading must be a finite number of degrees (got {self.heading_deg!r})")
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise ValueError(f"grid cell_m must be a positive number of metres (got {self.cell_m!r})")
        if len(self.origin_ne) != 2 or not all(math.isfinite(v) for v in self.origin_ne):
            raise ValueError(f"grid origin_ne must be (north, east) metres (got {self.origin_ne!r})")
        h = math.radians(self.heading_deg)
        object.__setattr__(self, "origin_ne", (float(self.origin_ne[0]), float(self.origin_ne[1])))
        object.__setattr__(self, "_cs", (math.cos(h), math.sin(h)))

    @property
    def rotated(self) -> bool:
        """Whether the grid is turned off north (heading != 0)."""
        return self.heading_deg != 0.0

    @property
    def _shifted(self) -> bool:
        return self.origin_ne != (0.0, 0.0)

    def grid_to_ned(self, g: np.ndarray | tuple[float, ...]) -> np.ndarray:
        """(..., 2) metres in the grid's own frame (ahead = -y, right = +x, about cell (0, 0)) ->
        (..., 2) NED (north, east). Vectors (velocities, offsets) rotate with `rotate_to_ned`."""
        g = self.rotate_to_ned(g)
        return g + np.asarray(self.origin_ne) if self._shifted else g

    def ned_to_grid(self, ne: np.ndarray | tuple[float, ...]) -> np.ndarray:
        """(..., 2) NED (north, east) -> (..., 2) metres in the grid's own frame."""
        p = np.asarray(ne, dtype=np.float64)
        if self._shifted:
            p = p - np.asarray(self.origin_ne)
        return self.rotate_to_grid(p)

    def rotate_to_ned(self, v: np.ndarray | tuple[float, ...]) -> np.ndarray:
        """(..., 2) a vector in the grid's frame -> the same vector in NED (no shift)."""
        v = np.asarray(v, dtype=np.float64)
        if not self.rotated:
            return v
        c, s = self._cs
        return np.stack([v[..., 0] * c - v[..., 1] * s, v[..., 0] * s + v[..., 1] * c], axis=-1)

    def rotate_to_grid(self, v: np.ndarray | tuple[float, ...]) -> np.ndarray:
        """(..., 2) a vector in NED -> the same vector in the grid's frame (no shift)."""
        v = np.asarray(v, dtype=np.float64)
        if not self.rotated:
            return v
        c, s = self._cs
        return np.stack([v[..., 0] * c + v[..., 1] * s, -v[..., 0] * s + v[..., 1] * c], axis=-1)

    def cell_to_ned(self, cell: np.ndarray | tuple[float, float]) -> np.ndarray:
        """(..., 2) cells (x, y) -> (..., 2) metres (north, east). Fractional cells allowed."""
        return self.grid_to_ned(cell_to_ned(cell, self.cell_m))

    def ned_to_cell(self, ne: np.ndarray | tuple[float, float]) -> np.ndarray:
        """(..., 2) metres (north, east) -> (..., 2) fractional cells (x, y); round for a cell."""
        return ned_to_cell(self.ned_to_grid(ne), self.cell_m)

    def nearest_cell(self, ne: np.ndarray | tuple[float, float]) -> np.ndarray:
        """The integer cell a NED position falls in (cells are centred on their grid point)."""
        return np.rint(self.ned_to_cell(ne)).astype(np.int64)

    def cell_corners(self, cells: np.ndarray) -> np.ndarray:
        """(k, 2) integer cells -> (k, 4, 2) NED corners of their squares, in ring order."""
        off = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
        return self.cell_to_ned(np.asarray(cells, dtype=np.float64)[:, None, :] + off)
