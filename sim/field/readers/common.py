"""Checks every reader shares: numbers, WGS84 ranges, closing vertices, vertex counts."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from ..errors import FieldError
from ..shapes import Area, LatLon, Ring


def vertex(path: Path, label: str, lat: object, lon: object, order: str) -> LatLon:
    """One (lat, lon) in degrees, checked; `order` names the file's axis order for the hint
    (GeoJSON and KML write lon, lat; a QGC plan lat, lon), the usual cause of a swapped pair."""
    if isinstance(lat, bool) or isinstance(lon, bool) or not isinstance(lat, int | float) or \
            not isinstance(lon, int | float):
        raise FieldError(path, f"{label}: vertex {_show(lat, lon, order)} is not two numbers ({order})")
    la, lo = float(lat), float(lon)
    if not (math.isfinite(la) and math.isfinite(lo)):
        raise FieldError(path, f"{label}: vertex {_show(la, lo, order)} is not finite")
    if abs(la) > 90 or abs(lo) > 180:
        if abs(la) > 180 or abs(lo) > 360:
            raise FieldError(path, f"{label}: vertex {_show(la, lo, order)} is not in degrees: projected "
                                   f"coordinates? The file must be WGS84 longitude/latitude")
        raise FieldError(path, f"{label}: latitude {la:g} / longitude {lo:g} out of range "
                               f"(the file's order is {order}: are they swapped?)")
    return la, lo


def _show(lat: object, lon: object, order: str) -> str:
    return f"[{lon!r}, {lat!r}]" if order.startswith("lon") else f"[{lat!r}, {lon!r}]"


def ring(path: Path, label: str, vertices: Sequence[LatLon], closed_required: bool = False) -> Ring:
    """A ring from its vertices: the closing vertex (if any) and repeated neighbours dropped.
    `closed_required`: the format says the last vertex repeats the first (GeoJSON, RFC 7946
    3.1.6): an open ring there means a truncated or hand-edited file, so it is an error."""
    vs = list(vertices)
    if closed_required:
        if len(vs) < 4:
            raise FieldError(path, f"{label} has {len(vs)} position(s); a closed ring needs at least 4 "
                                   f"(3 vertices and the first repeated)")
        if vs[0] != vs[-1]:
            raise FieldError(path, f"{label} is not closed: its last position must repeat its first "
                                   f"(RFC 7946 3.1.6)")
    if len(vs) > 1 and vs[0] == vs[-1]:
        vs.pop()
    clean: list[LatLon] = []
    for v in vs:
        if not clean or clean[-1] != v:
            clean.append(v)
    if len(clean) > 1 and clean[0] == clean[-1]:
        clean.pop()
    if len(clean) < 3:
        raise FieldError(path, f"{label} has {len(clean)} distinct vertex(es); a polygon needs at least 3")
    return Ring(label, tuple(clean))


def pick_field(path: Path, areas: Sequence[Area], exclusions: Sequence[Area], what: str) -> tuple[Area, list[Area]]:
    """The field among polygons a file does not label: the largest (its extent in degrees,
    scaled by the latitude, is enough to rank them); every other one is a no-fly zone, as
    an operator draws a barn or a pond as a second polygon inside the paddock."""
    if not areas:
        raise FieldError(path, f"no field polygon found ({what})")
    if len(areas) == 1:
        return areas[0], list(exclusions)
    ranked = sorted(areas, key=_area_deg2, reverse=True)
    return ranked[0], list(ranked[1:]) + list(exclusions)


def _area_deg2(a: Area) -> float:
    vs = a.outer.vertices
    k = math.cos(math.radians(vs[0][0]))
    s = 0.0
    for (la1, lo1), (la2, lo2) in zip(vs, vs[1:] + vs[:1], strict=True):
        s += lo1 * k * la2 - lo2 * k * la1
    return abs(s) / 2


def no_holes_in_exclusion(path: Path, a: Area) -> None:
    """A no-fly polygon with a hole would be a place allowed inside a forbidden one; neither
    PX4's nor ArduPilot's fence can say that, so it is refused rather than flattened."""
    if a.holes:
        raise FieldError(path, f"{a.label} is a no-fly polygon with {len(a.holes)} inner ring(s); "
                               f"a no-fly polygon cannot have holes (draw it without them)")
