"""The gridded field: polygons in WGS84, the grid laid over them, each cell's class; built from
a reader's shapes (`build_field`), written as field.json (`write_field`) and read back,
validated, by every command that takes `--field` (`load_field`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field as dc_field
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_write_json, stamp
from sim.gridworld.coords import DEFAULT_CELL_M
from sim.gridworld.geodesy import HomePosition

from .errors import FieldError
from .frame import GridFrame
from .geometry import check_holes, check_ring
from .grid import default_heading, lay_grid, normalise_heading
from .mask import CHARS, FORBIDDEN, NAMES, OUTSIDE, SEARCHABLE, classify
from .projection import MAX_EXTENT_M, LocalProjection
from .readers.common import ring as _ring
from .readers.common import vertex as _vertex
from .readers.geojson import load_json
from .shapes import LatLon, Shapes

KIND = "uavsearch polygon field"
VERSION = 1
#: the most cells a grid may have (width x height, every class): the planners' and the
#: belief's memory and time grow with it; 10 000 is 200 m x 200 m at 2 m
MAX_CELLS = 10_000
#: the ground's altitude AMSL where the file gives none: HomePosition's default
DEFAULT_ALT_M = HomePosition().alt_m
RULE = ("outside: the cell's centre is not in the field's outer ring; forbidden: the centre is in "
        "it but the cell's square shares area with a hole or a no-fly polygon; searchable: the rest")
FRAME = ("cell (x, y) -> metres about origin (cell (0, 0)'s centre): north = -(y cos h + x sin h) * cell_m, "
         "east = (x cos h - y sin h) * cell_m, h = heading_deg (the bearing of -y, the move f)")
_CLASS_OF = {c: k for k, c in CHARS.items()}


@dataclass(frozen=True)
class NoFly:
    """A place inside which nothing is searched and nothing flies: a hole of the field's
    polygon ("hole") or a polygon of its own ("exclusion"); both become exclusion fences."""

    kind: str
    ring: tuple[LatLon, ...]
    name: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("hole", "exclusion"):
            raise ValueError(f"no-fly kind must be 'hole' or 'exclusion' (got {self.kind!r})")


#: what is left of a narrow no-fly zone in its fence (m across; `PolygonField.fence_rings`)
CORE_M = 0.5


@dataclass(frozen=True, eq=False)
class PolygonField:
    """A real field, gridded. Cell (x, y) is `classes[y, x]`; `mask` is what the grid world
    takes (True = searchable); `cell_to_ned` maps cells to metres about `origin`, the centre of
    cell (0, 0), at `heading_deg` (see `sim.field.frame`)."""

    source: str
    #: the field's outer ring (the inclusion polygon)
    outer: tuple[LatLon, ...]
    no_fly: tuple[NoFly, ...]
    origin: HomePosition
    heading_deg: float
    cell_m: float
    width: int
    height: int
    classes: np.ndarray
    frame: GridFrame = dc_field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.width, int) and isinstance(self.height, int) and self.width > 0 and self.height > 0):
            raise ValueError(f"width and height must be positive integers (got {self.width!r} x {self.height!r})")
        if self.width * self.height > MAX_CELLS:
            raise ValueError(f"{self.width} x {self.height} cells is over the limit of {MAX_CELLS}")
        c = np.array(self.classes, dtype=np.int8)
        if c.shape != (self.height, self.width):
            raise ValueError(f"classes must be (height, width) = ({self.height}, {self.width}) (got {c.shape})")
        if not np.isin(c, (OUTSIDE, SEARCHABLE, FORBIDDEN)).all():
            raise ValueError("classes must be 0 (outside), 1 (searchable) or 2 (forbidden)")
        if len(self.outer) < 3:
            raise ValueError(f"the field's ring needs at least 3 vertices (got {len(self.outer)})")
        c.setflags(write=False)
        object.__setattr__(self, "classes", c)
        object.__setattr__(self, "frame", GridFrame(self.heading_deg, self.cell_m))  # validates both

    @property
    def mask(self) -> np.ndarray:
        """(height, width) bool, True where a target may be and the vehicle may go."""
        m = self.classes == SEARCHABLE
        m.setflags(write=False)
        return m

    @property
    def searchable_cells(self) -> int:
        return int((self.classes == SEARCHABLE).sum())

    def counts(self) -> dict[str, int]:
        return {NAMES[k]: int((self.classes == k).sum()) for k in (SEARCHABLE, OUTSIDE, FORBIDDEN)}

    @property
    def projection(self) -> LocalProjection:
        return LocalProjection(self.origin)

    def cell_to_ned(self, cell: np.ndarray | tuple[float, float]) -> np.ndarray:
        """(..., 2) cells -> (..., 2) (north, east) metres about `origin`."""
        return self.frame.cell_to_ned(cell)

    def ned_to_cell(self, ne: np.ndarray | tuple[float, float]) -> np.ndarray:
        return self.frame.ned_to_cell(ne)

    def cell_to_latlon(self, cell: tuple[float, float]) -> LatLon:
        return self.projection.to_latlon(self.cell_to_ned(cell))[0]

    def rings_ne(self) -> tuple[np.ndarray, list[np.ndarray]]:
        """The field's outer ring and every no-fly ring as (n, 2) (north, east) metres."""
        p = self.projection
        return p.to_ne(self.outer), [p.to_ne(z.ring) for z in self.no_fly]

    def allowed(self, ne: np.ndarray) -> np.ndarray:
        """(..., 2) (north, east) metres about `origin` -> bool: inside the outer ring (or on it)
        and outside every no-fly polygon: where a setpoint may be (the flight checks' test)."""
        import shapely

        p = np.asarray(ne, dtype=np.float64)
        outer, no_fly = self.rings_ne()
        ok = shapely.intersects_xy(shapely.Polygon(outer[:, ::-1]), p[..., 1], p[..., 0])
        for r in no_fly:
            ok &= ~shapely.contains_xy(shapely.Polygon(r[:, ::-1]), p[..., 1], p[..., 0])
        return ok

    def fence_rings(self, margin_m: float) -> tuple[list[LatLon], list[list[LatLon]]]:
        """The fence's rings (lat, lon), margin_m of room for the autopilot's position estimate:
        the outer ring grown by it, each no-fly ring shrunk by it, down to a core CORE_M across
        where it is narrower (a 4 m pond keeps a 0.5 m core: an estimate there has the vehicle
        truly over the pond, or its bias 2.7 m, 4 sigma). An autopilot tests its estimate (truth + the receiver's bias, 0.7 m sd an
        axis in our SITL) against its fence, while the companion flies the true cell centres,
        half a cell or more inside the field and outside its no-fly zones: fenced on the rings
        themselves, a vehicle truly over a border cell would breach on its bias. Mitred
        corners keep a vertex count autopilots take."""
        import shapely

        if not (math.isfinite(margin_m) and margin_m >= 0):
            raise ValueError(f"fence margin must be >= 0 m (got {margin_m!r})")
        outer, no_fly = self.rings_ne()
        p = self.projection

        def grown(ring: np.ndarray, by: float) -> np.ndarray:
            poly = shapely.Polygon(ring[:, ::-1])
            if by < 0:  # no deeper than leaves the core (the largest inscribed circle's radius less it)
                r = float(shapely.maximum_inscribed_circle(poly, 0.01).length)
                by = -min(-by, max(r - CORE_M / 2, 0.0))
            if by == 0:
                return ring
            g = poly.buffer(by, join_style="mitre", mitre_limit=3.0)
            if g.is_empty or g.geom_type != "Polygon":
                return ring
            return np.asarray(g.exterior.coords)[:-1, ::-1]

        return (p.to_latlon(grown(outer, margin_m)),
                [p.to_latlon(grown(r, -margin_m)) for r in no_fly])

    def to_dict(self) -> dict[str, Any]:
        n = self.counts()
        return {
            "kind": KIND, "version": VERSION, "source": self.source,
            "wgs84": "vertices are [lat, lon] degrees on WGS84; a ring does not repeat its first vertex",
            "outer": [list(v) for v in self.outer],
            "no_fly": [{"kind": z.kind, "name": z.name, "ring": [list(v) for v in z.ring]} for z in self.no_fly],
            "origin": {"lat": self.origin.lat_deg, "lon": self.origin.lon_deg, "alt": self.origin.alt_m},
            "heading_deg": self.heading_deg, "cell_m": self.cell_m, "width": self.width, "height": self.height,
            "frame": FRAME, "rule": RULE,
            "mask_legend": {CHARS[k]: NAMES[k] for k in (SEARCHABLE, OUTSIDE, FORBIDDEN)},
            "mask": ["".join(CHARS[int(v)] for v in row) for row in self.classes],
            "searchable_cells": n["searchable"], "outside_cells": n["outside"], "forbidden_cells": n["forbidden"],
        }


def _classes(origin: HomePosition, heading: float, cell_m: float, width: int, height: int,
             outer: Sequence[LatLon], no_fly: Sequence[NoFly]) -> np.ndarray:
    """The classes of the grid with cell (0, 0) at `origin`: the one computation that both
    building and loading run, so a file's mask can be checked against its polygons."""
    p = LocalProjection(origin)
    return classify(GridFrame(heading, cell_m), width, height, p.to_ne(outer), [p.to_ne(z.ring) for z in no_fly])


def _span(m: float) -> str:
    return f"{m / 1000:.1f} km" if m >= 2000 else f"{m:.0f} m"


def build_field(shapes: Shapes, path: Path | str, cell_m: float = DEFAULT_CELL_M,
                heading_deg: float | None = None, max_cells: int = MAX_CELLS) -> PolygonField:
    """Grid `shapes` (read from `path`, named in every error) at `heading_deg` (None: the
    minimum-area rectangle's) with cells of `cell_m` metres."""
    if not (isinstance(cell_m, int | float) and math.isfinite(cell_m) and cell_m > 0):
        raise FieldError(path, f"--cell-m must be a positive number of metres (got {cell_m!r})")
    if heading_deg is not None and not math.isfinite(heading_deg):
        raise FieldError(path, f"--heading must be a finite number of degrees (got {heading_deg!r})")
    alt = DEFAULT_ALT_M if shapes.alt_m is None else shapes.alt_m
    vs = shapes.field.outer.vertices
    proj0 = LocalProjection(HomePosition(float(np.mean([v[0] for v in vs])), float(np.mean([v[1] for v in vs])), alt))
    outer0 = proj0.to_ne(vs)
    check_ring(path, shapes.field.outer.label, outer0, proj0)
    holes0 = [proj0.to_ne(h.vertices) for h in shapes.field.holes]
    for h, ne in zip(shapes.field.holes, holes0, strict=True):
        check_ring(path, h.label, ne, proj0)
    check_holes(path, shapes.field.label, outer0, holes0, proj0)
    for a in shapes.exclusions:
        check_ring(path, a.outer.label, proj0.to_ne(a.outer.vertices), proj0)
    ns, ew = outer0.max(axis=0) - outer0.min(axis=0)
    if max(ns, ew) > MAX_EXTENT_M:
        raise FieldError(path, f"the field spans {_span(ns)} north-south x {_span(ew)} east-west; the limit "
                               f"is {MAX_EXTENT_M:.0f} m a side (the local projection's error grows as the "
                               f"square of the size: split the field)")
    heading = default_heading(outer0) if heading_deg is None else normalise_heading(float(heading_deg))
    frame0, w, h = lay_grid(outer0, heading, float(cell_m))
    if w * h > max_cells:
        k = math.ceil(float(cell_m) * math.sqrt(w * h / max_cells) * 10 - 1e-6) / 10
        raise FieldError(path, f"the grid is {w} x {h} = {w * h} cells of {float(cell_m):g} m, over the limit "
                               f"of {max_cells} cells; use a larger --cell-m (about {k:g}) or split the field")
    la, lo = proj0.to_latlon(np.array([frame0.origin_ne]))[0]
    origin = HomePosition(la, lo, alt)
    no_fly = tuple([NoFly("hole", h.vertices, None) for h in shapes.field.holes]
                   + [NoFly("exclusion", a.outer.vertices, a.name) for a in shapes.exclusions])
    classes = _classes(origin, heading, float(cell_m), w, h, vs, no_fly)
    if not (classes == SEARCHABLE).any():
        raise FieldError(path, f"no cell of the {w} x {h} grid is searchable: the field is smaller than a "
                               f"{float(cell_m):g} m cell or covered by no-fly zones (try a smaller --cell-m)")
    return PolygonField(shapes.source, vs, no_fly, origin, heading, float(cell_m), w, h, classes)


def write_field(path: Path | str, f: PolygonField, config: Any = None, **extra: Any) -> None:
    """field.json, atomically, with provenance (config: what the command was given)."""
    atomic_write_json(path, {**f.to_dict(), "provenance": stamp(config, None, **extra)})


def _num(path: Path, d: dict, key: str, kind: type = float) -> Any:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int | float) or (kind is int and not isinstance(v, int)) \
            or not math.isfinite(v):
        raise FieldError(path, f"{key} must be {'an integer' if kind is int else 'a number'} (got {v!r})")
    return kind(v)


def load_field(path: Path | str) -> PolygonField:
    """A field.json that `uavsearch field` wrote, validated: its polygons, its grid, and its
    mask recomputed from the polygons and compared, so a hand-edited or truncated file is
    refused with one line rather than flown."""
    path = Path(path)
    d = load_json(path, "field.json")
    if not isinstance(d, dict) or d.get("kind") != KIND:
        got = d.get("kind") if isinstance(d, dict) else type(d).__name__
        hint = " (that is the SITL's field file; `uavsearch field FILE` writes this one)" \
            if got == "uavsearch field" else " (`uavsearch field FILE` writes it)"
        raise FieldError(path, f"is not a polygon field file: kind {got!r}, not {KIND!r}{hint}")
    if d.get("version") != VERSION:
        raise FieldError(path, f"is version {d.get('version')!r}; this uavsearch reads version {VERSION}")
    order = "lat, lon"
    if not isinstance(d.get("outer"), list):
        raise FieldError(path, "outer must be a list of [lat, lon] vertices")
    outer = _ring(path, "outer", [_pair(path, "outer", v, order) for v in d["outer"]]).vertices
    no_fly = []
    for i, z in enumerate(d.get("no_fly") or []):
        if not isinstance(z, dict) or z.get("kind") not in ("hole", "exclusion") or not isinstance(z.get("ring"), list):
            raise FieldError(path, f"no_fly {i} must be {{\"kind\": \"hole\" | \"exclusion\", \"ring\": [...]}}")
        name = z.get("name")
        r = _ring(path, f"no_fly {i}", [_pair(path, f"no_fly {i}", v, order) for v in z["ring"]]).vertices
        no_fly.append(NoFly(z["kind"], r, name if isinstance(name, str) else None))
    o = d.get("origin")
    if not isinstance(o, dict):
        raise FieldError(path, "origin must be {\"lat\", \"lon\", \"alt\"}")
    try:
        origin = HomePosition(_num(path, o, "lat"), _num(path, o, "lon"), _num(path, o, "alt"))
    except ValueError as e:
        if isinstance(e, FieldError):
            raise
        raise FieldError(path, f"origin: {e}") from None
    heading, cell_m = _num(path, d, "heading_deg"), _num(path, d, "cell_m")
    w, h = _num(path, d, "width", int), _num(path, d, "height", int)
    if not cell_m > 0 or w < 1 or h < 1 or w * h > MAX_CELLS:
        raise FieldError(path, f"grid {w} x {h} of cell_m {cell_m:g} is not a grid of 1 to {MAX_CELLS} "
                               f"cells of positive size")
    rows = d.get("mask")
    if not isinstance(rows, list) or len(rows) != h or not all(isinstance(r, str) and len(r) == w for r in rows):
        raise FieldError(path, f"mask must be {h} rows of {w} characters (one per cell)")
    bad = sorted({ch for r in rows for ch in r} - set(_CLASS_OF))
    if bad:
        raise FieldError(path, f"mask holds {''.join(bad)!r}; its characters are " +
                         ", ".join(f"{c!r} {NAMES[k]}" for k, c in CHARS.items()))
    classes = np.array([[_CLASS_OF[ch] for ch in r] for r in rows], dtype=np.int8)
    n = int((classes == SEARCHABLE).sum())
    if d.get("searchable_cells") != n:
        raise FieldError(path, f"searchable_cells says {d.get('searchable_cells')!r}; the mask has {n}")
    if n == 0:
        raise FieldError(path, "no cell is searchable")
    again = _classes(origin, heading, cell_m, w, h, outer, no_fly)
    diff = np.argwhere(again != classes)
    if len(diff):
        y, x = diff[0]
        raise FieldError(path, f"the mask does not match its polygons ({len(diff)} cell(s); cell ({x}, {y}) is "
                               f"{NAMES[int(classes[y, x])]} in the file, {NAMES[int(again[y, x])]} by the "
                               f"polygons): regenerate it with uavsearch field")
    src = d.get("source") if isinstance(d.get("source"), str) else ""
    return PolygonField(src, outer, tuple(no_fly), origin, heading, cell_m, w, h, classes)


def _pair(path: Path, label: str, v: Any, order: str) -> LatLon:
    if not isinstance(v, list) or len(v) != 2:
        raise FieldError(path, f"{label}: vertex {str(v)[:40]} is not [lat, lon]")
    return _vertex(path, label, v[0], v[1], order)
