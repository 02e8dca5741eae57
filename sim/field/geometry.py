"""Geometry checks in metres, the same for every format: crossing rings, rings without area,
holes outside their field or crossing it. Each names the ring and where (lat, lon) it fails."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import shapely

from .errors import FieldError
from .projection import LocalProjection

#: a ring enclosing less than this (m^2) is a line drawn twice, not an area
MIN_AREA_M2 = 0.01
_AT = re.compile(r"\[\s*(-?[\d.eE+-]+)\s+(-?[\d.eE+-]+)\s*\]")


def _where(reason: str, proj: LocalProjection) -> str:
    """' near lat, lon' for a GEOS reason 'Self-intersection[east north]'."""
    m = _AT.search(reason)
    if not m:
        return ""
    lat, lon = proj.to_latlon(np.array([[float(m.group(2)), float(m.group(1))]]))[0]
    return f" near {lat:.6f}, {lon:.6f}"


def check_ring(path: Path | str, label: str, ne: np.ndarray, proj: LocalProjection) -> None:
    """A ring that does not cross itself and encloses an area."""
    poly = shapely.Polygon(ne[:, ::-1])
    if not shapely.LinearRing(ne[:, ::-1]).is_simple:
        reason = shapely.is_valid_reason(poly)
        raise FieldError(path, f"{label} crosses itself{_where(reason, proj)} (a bow-tie: are its vertices "
                               f"out of order?)")
    if poly.area < MIN_AREA_M2:
        raise FieldError(path, f"{label} encloses no area (its {len(ne)} vertices lie on one line)")


def check_holes(path: Path | str, label: str, outer: np.ndarray, holes: list[np.ndarray],
                proj: LocalProjection) -> None:
    """Holes inside their polygon, not crossing it nor each other."""
    if not holes:
        return
    poly = shapely.Polygon(outer[:, ::-1], [h[:, ::-1] for h in holes])
    if poly.is_valid:
        return
    reason = shapely.is_valid_reason(poly)
    what = reason.split("[")[0].strip()
    plain = {"Hole lies outside shell": "a hole lies outside it",
             "Self-intersection": "a hole crosses its outer ring or another hole",
             "Interior is disconnected": "its holes cut it in pieces",
             "Nested holes": "a hole lies inside another hole"}.get(what, what)
    raise FieldError(path, f"{label}: {plain}{_where(reason, proj)}")
