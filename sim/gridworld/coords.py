"""Grid cell <-> local NED. The only place this mapping is written; everything else calls it.

Cell (x, y) sits at north = -y * cell, east = x * cell from the field origin (cell (0, 0)),
so f (-y) flies north and r (+x) flies east.
"""

from __future__ import annotations

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
