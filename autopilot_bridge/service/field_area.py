"""A real field as the companion flies it: the grid's heading, the searchable cells, and the
field's edge as borders the camera can register on.

The companion works in the grid's own frame: "field north, east" everywhere in the service
(the position posterior, the bias, the map, the camera's offsets, the local setpoints) means
ahead (-y, the move f) and right (+x), which is north and east on today's north-aligned grid.
Only what crosses the link is turned, by `sim.gridworld.coords.GridFrame`, the one cell <-> NED
mapping: GPS fixes, the autopilot's estimate, home and its local origin into the grid's frame
as they come in (`TelemetryIntake`), setpoints back into NED as they go out (`Pilot`). The
camera's gimbal holds the image aligned to the grid (image top = f), so a frame's offsets are
in the grid's frame already. At heading 0 nothing is turned and every number is today's.

A polygon's edge is not the grid's outer border (`edges.border_ne`, a rectangle's): a border
seen in a frame is matched to the polygon's edges that run along the same grid axis, with the
grass on the side the frame shows it, nearest to where the posterior puts it (`border_along`).

Duck-typed on `sim.field.PolygonField` (`heading_deg`, `cell_m`, `mask`, `rings_ne()`), as
`fence.FencePlan.of_field` is: the companion does not import the field module."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.gridworld import GridFrame
from sim.gridworld.masks import largest_component

#: a polygon edge within this many degrees of a grid axis is a border the frame can show as a
#: row or a column (edges.find_edges: its lines must agree within a pixel across the frame;
#: 1.5 deg over the 8.3 m footprint is 0.2 m, 1.3 px at 3.5 m)
PARALLEL_DEG = 1.5
#: a border sighting is matched only to a polygon edge this close (m, along the axis) to where
#: the posterior puts it: further, it is some other edge (a corner's), left out
MATCH_M = 2.5


@dataclass(frozen=True)
class FieldArea:
    """What the companion knows of a polygon field beside the rectangle's `GridConfig`."""

    #: cell <-> field NED (north, east about cell (0, 0)) at the field's heading
    frame: GridFrame
    #: (height, width) bool: the cells searched (the largest 4-connected part of the field's
    #: searchable cells, which the vehicle reaches without crossing a no-fly zone)
    mask: np.ndarray
    #: the field's outer ring (the inclusion polygon) in the grid's frame (ahead, right metres)
    outer_grid: np.ndarray
    _borders: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        m = np.array(self.mask, dtype=bool)
        if m.ndim != 2 or m.sum() < 2:
            raise ValueError(f"a field's mask must be (height, width) bool with 2 or more searchable cells (got {m.shape})")
        m.setflags(write=False)
        object.__setattr__(self, "mask", m)
        ring = np.array(self.outer_grid, dtype=float)
        if ring.ndim != 2 or ring.shape[1] != 2 or len(ring) < 3:
            raise ValueError(f"outer_grid must be (n >= 3, 2) metres (got {ring.shape})")
        object.__setattr__(self, "outer_grid", ring)
        object.__setattr__(self, "_borders", _borders(ring))

    @classmethod
    def of_field(cls, f) -> FieldArea:
        """From a `sim.field.PolygonField` (duck-typed)."""
        frame = GridFrame(float(f.heading_deg), float(f.cell_m))
        outer, _ = f.rings_ne()
        return cls(frame, largest_component(np.asarray(f.mask, bool)), frame.ned_to_grid(np.asarray(outer)))

    @property
    def heading_deg(self) -> float:
        return self.frame.heading_deg

    def searchable(self, cell: np.ndarray) -> bool:
        """Whether cell (x, y) is one the search may fly to."""
        x, y = int(cell[0]), int(cell[1])
        h, w = self.mask.shape
        return bool(0 <= x < w and 0 <= y < h and self.mask[y, x])

    def border_along(self, axis: int, side: int, camera_ne: np.ndarray, offset_m: float,
                     reach_m: float) -> float | None:
        """Where (grid-frame metres along `axis`) the polygon border a frame shows at `offset_m`
        from the camera lies, the camera believed at camera_ne: the polygon edges along that
        axis with the grass on the side the frame shows (side +1: the border ahead (right) of
        the grass), whose span across the axis the frame covers (reach_m either side), nearest
        to camera + offset; None when none lies within MATCH_M."""
        best, best_d = None, MATCH_M
        other = 1 - axis
        guess = float(camera_ne[axis]) + offset_m
        across = float(camera_ne[other])
        for a_pos, b_pos, a_across, b_across in self._borders[axis][side]:
            lo, hi = min(a_across, b_across), max(a_across, b_across)
            if hi < across - reach_m or lo > across + reach_m:
                continue
            # the edge's place along the axis where the camera is across it (an edge up to
            # PARALLEL_DEG off the axis moves by 1.2 m along a 45 m side)
            k = min(max((across - a_across) / (b_across - a_across), 0.0), 1.0)
            pos = a_pos + (b_pos - a_pos) * k
            d = abs(pos - guess)
            if d < best_d:
                best, best_d = pos, d
        return best


def _borders(ring: np.ndarray) -> tuple:
    """Per axis (0: edges running across north, 1: across east), per side (+1, -1): the ring's
    edges within PARALLEL_DEG of the other axis as (its ends along the axis, its ends across it)."""
    import shapely

    poly = shapely.Polygon(ring[:, ::-1])  # shapely's x = east, y = north
    tol = math.tan(math.radians(PARALLEL_DEG))
    out: tuple = ({1: [], -1: []}, {1: [], -1: []})
    for a, b in zip(ring, np.roll(ring, -1, axis=0), strict=True):
        d = b - a
        for axis in (0, 1):
            other = 1 - axis
            if abs(d[other]) < 1e-9 or abs(d[axis]) > tol * abs(d[other]):
                continue
            mid = (a + b) / 2
            probe = mid.copy()
            probe[axis] -= 0.3  # a step towards lower values along the axis: inside means side +1
            inside_below = bool(shapely.contains_xy(poly, probe[1], probe[0]))
            side = 1 if inside_below else -1
            out[axis][side].append((float(a[axis]), float(b[axis]), float(a[other]), float(b[other])))
    return out


def field_view_blocked(area: FieldArea, cell: np.ndarray) -> np.ndarray:
    """(3, 3) uint8: the view's off-map channel on the field: cells off the grid or masked,
    as the grid world shows them (`sim.gridworld.masks.blocked_view`)."""
    from sim.gridworld.masks import blocked_view

    return blocked_view(area.mask[None], np.asarray(cell, dtype=np.int64)[None])[0].astype(np.uint8)


def field_map_valid(area: FieldArea, maps: np.ndarray, variant: str, cell: np.ndarray,
                    n_actions: int) -> tuple[np.ndarray, np.ndarray]:
    """The policy's map and valid moves on the field, as the grid world gives them on a mask:
    masked cells read as visited on the spatial maps (nothing to search there) and a move into
    one is off the map (`sim.gridworld.masks.neighbour_valid`)."""
    from sim.gridworld.masks import neighbour_valid
    from sim.gridworld.observations import VISITED_VALUE

    maps = np.array(maps, copy=True)
    if variant != "spatiotemporal":
        maps[:, ~area.mask] = VISITED_VALUE
    valid = neighbour_valid(area.mask[None], np.asarray(cell, dtype=np.int64)[None], n_actions)[0]
    return maps, valid
