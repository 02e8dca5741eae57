"""QGroundControl `.plan` (JSON, fileType "Plan"): the geofence's polygons, or a Survey's.

geoFence version 2 holds `polygons` ({"inclusion": bool, "polygon": [[lat, lon], ...]}) and
`circles` ({"inclusion": bool, "circle": {"center": [lat, lon], "radius": m}}); version 1 held
one inclusion `polygon`. The field is the one inclusion polygon; without one, the mission's
Survey item's polygon (what an operator draws to have an area covered). Exclusion polygons
and exclusion circles are no-fly zones; a circle becomes a polygon round it (circumscribed, so
it covers the whole circle). QGC writes rings without repeating the first vertex. Vertices are
[lat, lon], QGC's order (GeoJSON's is the reverse)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sim.gridworld.geodesy import HomePosition

from ..errors import FieldError
from ..shapes import Area, Shapes
from .common import ring, vertex
from .geojson import load_json

ORDER = "lat, lon"
#: vertices of the polygon that stands for an exclusion circle
CIRCLE_VERTICES = 36


def read_plan(path: Path) -> Shapes:
    doc = load_json(path, "QGroundControl plan")
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        got = doc.get("fileType") if isinstance(doc, dict) else type(doc).__name__
        raise FieldError(path, f"is not a QGroundControl plan (fileType {got!r}, not 'Plan')")
    fence = doc.get("geoFence") or {}
    mission = doc.get("mission") or {}
    if not isinstance(fence, dict) or not isinstance(mission, dict):
        raise FieldError(path, "geoFence and mission must be JSON objects")
    inclusions: list[Area] = []
    exclusions: list[Area] = []
    polys = fence.get("polygons", [])
    if not isinstance(polys, list):
        raise FieldError(path, "geoFence polygons must be a list")
    for i, p in enumerate(polys):
        label = f"geoFence polygon {i}"
        if not isinstance(p, dict) or not isinstance(p.get("inclusion", True), bool):
            raise FieldError(path, f"{label} must be an object with \"inclusion\": true or false")
        a = Area(label, _ring(path, p.get("polygon"), f"{label} ring"))
        (inclusions if p.get("inclusion", True) else exclusions).append(a)
    if "polygon" in fence and fence["polygon"]:  # geoFence version 1: one inclusion polygon
        inclusions.append(Area("geoFence polygon", _ring(path, fence["polygon"], "geoFence polygon ring")))
    circles_in = 0
    circles = fence.get("circles", [])
    if not isinstance(circles, list):
        raise FieldError(path, "geoFence circles must be a list")
    for i, c in enumerate(circles):
        label = f"geoFence circle {i}"
        if not isinstance(c, dict) or not isinstance(c.get("circle"), dict):
            raise FieldError(path, f"{label} must be an object with a \"circle\"")
        if c.get("inclusion", True):
            circles_in += 1  # a cylinder round home, like GF_MAX_HOR_DIST: not the field's shape
            continue
        exclusions.append(Area(label, _circle(path, c["circle"], f"{label}")))
    surveys = []
    items = mission.get("items", [])
    if not isinstance(items, list):
        raise FieldError(path, "mission items must be a list")
    for i, it in enumerate(items):
        if isinstance(it, dict) and it.get("type") == "ComplexItem" and \
                str(it.get("complexItemType", "")).lower() == "survey":
            surveys.append(Area(f"mission item {i} (Survey)", _ring(path, it.get("polygon"), f"mission item {i} (Survey) polygon")))
    alt = _home_alt(mission)
    if len(inclusions) > 1:
        raise FieldError(path, f"has {len(inclusions)} inclusion polygons; a field is one: keep the one "
                               f"drawn round the field (the others as exclusions, or in another plan)")
    notes = []
    if inclusions:
        field = inclusions[0]
        src = "QGroundControl plan: the geoFence inclusion polygon"
        if surveys:
            notes.append(f"{len(surveys)} Survey polygon(s) not used")
    elif surveys:
        if len(surveys) > 1:
            raise FieldError(path, f"has no inclusion polygon and {len(surveys)} Survey items; a field is one "
                                   f"(draw an inclusion fence round the field, or keep one Survey)")
        field = surveys[0]
        src = f"QGroundControl plan: the Survey polygon ({field.label})"
    else:
        what = f"{circles_in} inclusion circle(s), " if circles_in else ""
        raise FieldError(path, f"no polygon found ({what}{len(exclusions)} exclusion(s), no inclusion "
                               f"polygon, no Survey item); draw the field as an inclusion polygon")
    if circles_in:
        notes.append(f"{circles_in} inclusion circle(s) not part of the field")
    if exclusions:
        notes.append(f"{len(exclusions)} exclusion(s) no-fly")
    return Shapes(field, tuple(exclusions), src + (f" ({'; '.join(notes)})" if notes else ""), alt)


def _ring(path: Path, pts: Any, label: str):  # noqa: ANN202 - a Ring
    if not isinstance(pts, list):
        raise FieldError(path, f"{label} must be a list of [lat, lon] vertices")
    vs = []
    for p in pts:
        if not isinstance(p, list) or len(p) < 2:
            raise FieldError(path, f"{label}: vertex {str(p)[:40]} is not [lat, lon]")
        vs.append(vertex(path, label, p[0], p[1], ORDER))
    return ring(path, label, vs)


def _circle(path: Path, c: dict, label: str):  # noqa: ANN202 - a Ring
    centre, r = c.get("center"), c.get("radius")
    if not isinstance(centre, list) or len(centre) < 2:
        raise FieldError(path, f"{label}: center must be [lat, lon]")
    lat, lon = vertex(path, label, centre[0], centre[1], ORDER)
    if isinstance(r, bool) or not isinstance(r, int | float) or not math.isfinite(r) or not r > 0:
        raise FieldError(path, f"{label}: radius must be a positive number of metres (got {r!r})")
    home = HomePosition(lat, lon, 0.0)
    a = np.arange(CIRCLE_VERTICES) * (2 * math.pi / CIRCLE_VERTICES)
    rr = float(r) / math.cos(math.pi / CIRCLE_VERTICES)  # circumscribed: the polygon covers the circle
    vs = [home.ned_to_geodetic(np.array([rr * math.cos(t), rr * math.sin(t), 0.0]))[:2] for t in a]
    return ring(path, f"{label} (radius {float(r):g} m)", vs)


def _home_alt(mission: dict) -> float | None:
    h = mission.get("plannedHomePosition")
    if isinstance(h, list) and len(h) >= 3 and isinstance(h[2], int | float) and not isinstance(h[2], bool) \
            and math.isfinite(h[2]):
        return float(h[2])
    return None
