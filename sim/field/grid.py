"""Laying the grid over a polygon: its heading and its extent.

The default heading is the minimum-area bounding rectangle's (shapely's
`minimum_rotated_rectangle`): an L-shaped paddock drawn at 30 degrees gets a grid along its
arms, so its edges run along cell edges and few cells are cut. Of the rectangle's two edge
directions (90 degrees apart, the same grid lines) the one nearest north is taken, in
[-45, 45), so a field drawn north-aligned keeps today's grid (heading 0)."""

from __future__ import annotations

import math

import numpy as np
import shapely

from .frame import GridFrame

#: headings are rounded to this many decimals of a degree (a rectangle's edge is computed in
#: floating point: a north-aligned field would otherwise get a heading of 1e-14)
HEADING_DECIMALS = 6
#: a polygon may overhang its grid by up to half this share of a cell on each side (5 cm at 2 m)
SPAN_SLACK = 0.05


def default_heading(outer_ne: np.ndarray) -> float:
    """The minimum-area bounding rectangle's heading, degrees in [-45, 45)."""
    poly = shapely.Polygon(outer_ne[:, ::-1])  # shapely x = east, y = north
    rect = np.asarray(shapely.minimum_rotated_rectangle(poly).exterior.coords)
    de, dn = rect[1] - rect[0]
    return normalise_heading(math.degrees(math.atan2(de, dn)), quarter=True)


def normalise_heading(deg: float, quarter: bool = False) -> float:
    """A heading in [-180, 180) (or, `quarter`, modulo 90 in [-45, 45)); no -0.0."""
    period = 90.0 if quarter else 360.0
    h = round((deg + period / 2) % period - period / 2, HEADING_DECIMALS)
    if h >= period / 2:
        h -= period
    return h + 0.0  # -0.0 -> 0.0


def lay_grid(outer_ne: np.ndarray, heading_deg: float, cell_m: float) -> tuple[GridFrame, int, int]:
    """The smallest grid of whole cells at `heading_deg` covering the polygon's vertices,
    centred on them; returns its frame (cell (0, 0)'s centre as origin) and width, height."""
    c = GridFrame(heading_deg, cell_m).ned_to_cell(outer_ne)
    lo, hi = c.min(axis=0), c.max(axis=0)
    # a span of k cells and a little (SPAN_SLACK) is k cells: vertices are drawn to a cm or so,
    # and a heading off by 0.003 deg turns a 48 m side 3 mm wider; an extra row of cells whose
    # centres all sit on the field's edge (half in, half out by rounding) would help nobody
    n = np.maximum(1, np.ceil(hi - lo - SPAN_SLACK)).astype(np.int64)
    start = (lo + hi) / 2 - n / 2 + 0.5  # cell (0, 0)'s centre, in the unshifted frame's cells
    origin = GridFrame(heading_deg, cell_m).cell_to_ned(start)
    return GridFrame(heading_deg, cell_m, (float(origin[0]), float(origin[1]))), int(n[0]), int(n[1])
