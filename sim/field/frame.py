"""Grid cell <-> local NED for a grid at any heading and origin.

`sim.gridworld.coords` writes the mapping for today's north-aligned grid: cell (x, y) at
north = -y * cell, east = x * cell from cell (0, 0)'s centre, cell (0, 0) top-left, f (-y)
north, r (+x) east. A real field's grid keeps that convention in its own rotated frame:
`heading_deg` is the bearing (degrees clockwise from true north) of the grid's -y axis, the
direction the move f flies; +x (the move r) points at heading + 90. So heading 0 is today's
grid, and this class calls `sim.gridworld.coords` for the grid-frame part and only rotates and
shifts it: at heading 0 and origin (0, 0) it returns that function's result unchanged, bit for
bit. Vectorised over any leading shape."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.gridworld import coords
from sim.gridworld.coords import DEFAULT_CELL_M

from .errors import FieldError


@dataclass(frozen=True)
class GridFrame:
    heading_deg: float = 0.0
    cell_m: float = DEFAULT_CELL_M
    #: cell (0, 0)'s centre in the local NED frame (north, east), metres
    origin_ne: tuple[float, float] = (0.0, 0.0)
    _cs: tuple[float, float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not math.isfinite(self.heading_deg):
            raise FieldError("grid", f"heading must be a finite number of degrees (got {self.heading_deg!r})")
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise FieldError("grid", f"cell_m must be a positive number of metres (got {self.cell_m!r})")
        if len(self.origin_ne) != 2 or not all(math.isfinite(v) for v in self.origin_ne):
            raise FieldError("grid", f"origin_ne must be (north, east) metres (got {self.origin_ne!r})")
        h = math.radians(self.heading_deg)
        object.__setattr__(self, "origin_ne", (float(self.origin_ne[0]), float(self.origin_ne[1])))
        object.__setattr__(self, "_cs", (math.cos(h), math.sin(h)))

    @property
    def _rotated(self) -> bool:
        return self.heading_deg != 0.0

    @property
    def _shifted(self) -> bool:
        return self.origin_ne != (0.0, 0.0)

    def cell_to_ned(self, cell: np.ndarray | tuple[float, float]) -> np.ndarray:
        """(..., 2) cells (x, y) -> (..., 2) metres (north, east). Fractional cells allowed."""
        g = coords.cell_to_ned(cell, self.cell_m)  # the grid's own frame: (ahead, right)
        if self._rotated:
            c, s = self._cs
            g = np.stack([g[..., 0] * c - g[..., 1] * s, g[..., 0] * s + g[..., 1] * c], axis=-1)
        if self._shifted:
            g = g + np.asarray(self.origin_ne)
        return g

    def ned_to_cell(self, ne: np.ndarray | tuple[float, float]) -> np.ndarray:
        """(..., 2) metres (north, east) -> (..., 2) fractional cells (x, y); round for a cell."""
        p = np.asarray(ne, dtype=np.float64)
        if self._shifted:
            p = p - np.asarray(self.origin_ne)
        if self._rotated:
            c, s = self._cs
            p = np.stack([p[..., 0] * c + p[..., 1] * s, -p[..., 0] * s + p[..., 1] * c], axis=-1)
        return coords.ned_to_cell(p, self.cell_m)

    def nearest_cell(self, ne: np.ndarray | tuple[float, float]) -> np.ndarray:
        """The integer cell a NED position falls in (cells are centred on their grid point)."""
        return np.rint(self.ned_to_cell(ne)).astype(np.int64)

    def cell_corners(self, cells: np.ndarray) -> np.ndarray:
        """(k, 2) integer cells -> (k, 4, 2) NED corners of their squares, in ring order."""
        off = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
        return self.cell_to_ned(np.asarray(cells, dtype=np.float64)[:, None, :] + off)
