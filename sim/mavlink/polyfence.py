"""Polygon and circle fences as PX4 and ArduCopter store and test them: the zones built from
an uploaded fence (MAV_MISSION_TYPE_FENCE items 5001-5004, 5000) and the point test each
autopilot runs. Looked up, not guessed:

- PX4 main 2026-08 (src/modules/navigator/geofence.cpp): `Geofence::_updateFence` walks the
  items: a polygon takes the next `vertex_count` items whatever they are, a circle one item, a
  return point is skipped, any other command is skipped ("unhandled Fence command"); a zone
  that does not hold home ("Geofence invalid, doesn't contain Home position") or, while flying
  with GF_ACTION set, the vehicle is dropped. `insidePolygon` is PNPOLY on lat/lon in degrees
  (doubles); a point passes when it passes every zone (`isInsidePolygonOrCircle`).
- ArduCopter 2024-05 (libraries/AC_Fence/AC_PolyFence_loader.cpp): `validate_fence` checks
  the whole upload before it is stored (its STATUSTEXTs are sent here word for word);
  `breached` tests lat/lon in 1e-7 degrees with `Polygon_outside` (AP_Math/polygon.cpp:
  integer cross products, exact), inclusion zones intersected (FENCE_OPTIONS bit 1 unset).

A polygon whose vertex count runs past the end of the upload is kept by PX4 with the items
there are; its PNPOLY reads a vertex that is not there and stops at once, so it holds no point
(an inclusion zone then fails the home check and is dropped). Altitudes of fence items are
not used by either (PX4's vertical limits come from a fence file, not the mission protocol).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

M = mavlink
INCLUSION, EXCLUSION = M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CIRCLE_IN, CIRCLE_OUT = M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
RETURN_POINT = M.MAV_CMD_NAV_FENCE_RETURN_POINT
POLYGONS = frozenset({INCLUSION, EXCLUSION})
CIRCLES = frozenset({CIRCLE_IN, CIRCLE_OUT})
EARTH_R = 6378137.0


@dataclass(frozen=True)
class FenceItem:
    """One stored fence item, as it is sent back on download."""

    seq: int
    frame: int
    command: int
    param1: float  # polygons: vertex count; circles: radius (m)
    x: int  # lat * 1e7
    y: int  # lon * 1e7
    z: float


@dataclass(frozen=True)
class Zone:
    """One polygon (vertices in 1e-7 degrees) or circle (centre, radius m)."""

    command: int
    vertices: tuple[tuple[int, int], ...]
    radius_m: float = 0.0
    complete: bool = True  # False: PX4 read past the end of the upload (holds no point)

    @property
    def inclusion(self) -> bool:
        return self.command in (INCLUSION, CIRCLE_IN)


def _circle_distance_m(lat: float, lon: float, c_lat: float, c_lon: float) -> float:
    """Flat-earth distance about the centre (both autopilots project locally)."""
    dn = math.radians(lat - c_lat) * EARTH_R
    de = math.radians(lon - c_lon) * EARTH_R * math.cos(math.radians(c_lat))
    return math.hypot(dn, de)


# -- PX4 -------------------------------------------------------------------------------------
def px4_zones(items: list[FenceItem]) -> list[Zone]:
    """Geofence::_updateFence's walk over the stored items (before its home and position checks)."""
    zones, seq = [], 0
    while seq < len(items):
        it = items[seq]
        if it.command in CIRCLES:
            zones.append(Zone(it.command, ((it.x, it.y),), float(it.param1)))
            seq += 1
        elif it.command in POLYGONS:
            n = int(it.param1 + 0.5) & 0xFFFF  # (uint16_t)(param1 + 0.5f)
            if n == 0:
                seq += 1  # "Polygon with 0 vertices. Skipping"
                continue
            verts = tuple((v.x, v.y) for v in items[seq:seq + n])
            zones.append(Zone(it.command, verts, complete=len(verts) == n))
            seq += n
        else:  # return point, or "unhandled Fence command"
            seq += 1
    return zones


def px4_inside_polygon(z: Zone, lat: float, lon: float) -> bool:
    """Geofence::insidePolygon: PNPOLY on degrees, as PX4 writes it."""
    if not z.complete:
        return False
    c = False
    v = [(x * 1e-7, y * 1e-7) for x, y in z.vertices]
    j = len(v) - 1
    for i in range(len(v)):
        (lat_i, lon_i), (lat_j, lon_j) = v[i], v[j]
        if (lon_i >= lon) != (lon_j >= lon) and lat <= (lat_j - lat_i) * (lon - lon_i) / (lon_j - lon_i) + lat_i:
            c = not c
        j = i
    return c


def px4_zone_passes(z: Zone, lat: float, lon: float) -> bool:
    """Geofence::checkPointAgainstPolygonCircle."""
    if z.command in CIRCLES:
        inside = _circle_distance_m(lat, lon, z.vertices[0][0] * 1e-7, z.vertices[0][1] * 1e-7) < z.radius_m
    else:
        inside = px4_inside_polygon(z, lat, lon)
    return inside if z.inclusion else not inside


def px4_allows(zones: list[Zone], lat: float, lon: float) -> bool:
    """Geofence::isInsidePolygonOrCircle: every zone passes (none: every point does)."""
    return all(px4_zone_passes(z, lat, lon) for z in zones)


# -- ArduPilot -------------------------------------------------------------------------------
def ardupilot_validate(items: list[FenceItem]) -> str | None:
    """AC_PolyFence_loader::validate_fence: None, or its STATUSTEXT for the first fault."""
    expecting, expected_left, orig = None, 0, 0
    seen_return = False
    for it in items:
        check_latlon = False
        if it.command in POLYGONS:
            n = int(it.param1) & 0xFF  # AC_PolyFenceItem.vertex_count is a uint8_t
            if n < 3:
                return f"Invalid vertex count ({n})"
            if expected_left == 0:
                expected_left, orig, expecting = n, n, it.command
            elif it.command != expecting:
                return f"Received incorrect vertex type (want={_ap_type(expecting)} got={_ap_type(it.command)})"
            elif n != orig:
                return f"Unexpected vertex count want={orig} got={n}\n"  # its format string's newline
            expected_left -= 1
            check_latlon = True
        elif it.command in CIRCLES:
            if expected_left:
                return f"Received incorrect type (want={_ap_type(expecting)} got={_ap_type(it.command)})"
            if not it.param1 > 0:
                return "Non-positive circle radius"
            check_latlon = True
        elif it.command == RETURN_POINT:
            if expected_left:
                return f"Received incorrect type (want={_ap_type(expecting)} got={_ap_type(it.command)})"
            if seen_return:
                return "Multiple return points"
            seen_return, check_latlon = True, True
        if check_latlon and not (abs(it.x) <= 90e7 and abs(it.y) <= 180e7):  # check_latlng
            return "Bad lat or lon"
    if expected_left:
        return "Incorrect item count"
    return None


def _ap_type(command: int | None) -> int:
    """AC_PolyFenceType numbers (AC_PolyFence_loader.h), as validate_fence prints them."""
    return {INCLUSION: 98, EXCLUSION: 97, CIRCLE_IN: 92, CIRCLE_OUT: 93, RETURN_POINT: 95}.get(command, 99)


def ardupilot_zones(items: list[FenceItem]) -> list[Zone]:
    """The loaded boundaries of a validated upload."""
    zones, seq = [], 0
    while seq < len(items):
        it = items[seq]
        if it.command in POLYGONS:
            n = int(it.param1) & 0xFF
            zones.append(Zone(it.command, tuple((v.x, v.y) for v in items[seq:seq + n])))
            seq += n
        else:
            if it.command in CIRCLES:
                zones.append(Zone(it.command, ((it.x, it.y),), float(it.param1)))
            seq += 1
    return zones


def polygon_outside(p: tuple[int, int], verts: tuple[tuple[int, int], ...]) -> bool:
    """AP_Math's Polygon_outside<int32_t>: PNPOLY with sign checks and exact products."""
    n = len(verts)
    if n >= 4 and verts[-1] == verts[0]:
        n -= 1
    px, py = p
    outside = True
    for i in range(n):
        j = 0 if i + 1 >= n else i + 1
        (xi, yi), (xj, yj) = verts[i], verts[j]
        if (yi > py) == (yj > py):
            continue
        dx1, dx2, dy1, dy2 = px - xi, xj - xi, py - yi, yj - yi
        m1 = (-1 if dx1 < 0 else 1) * (-1 if dy2 < 0 else 1)
        m2 = (-1 if dx2 < 0 else 1) * (-1 if dy1 < 0 else 1)
        if dy2 < 0:
            if m1 > m2 or (m1 == m2 and dx1 * dy2 > dx2 * dy1):
                outside = not outside
        elif m1 < m2 or (m1 == m2 and dx1 * dy2 < dx2 * dy1):
            outside = not outside
    return outside


def ardupilot_breached(zones: list[Zone], lat_e7: int, lon_e7: int) -> bool:
    """AC_PolyFence_loader::breached(loc): outside an inclusion zone or inside an exclusion."""
    p = (lat_e7, lon_e7)
    for z in zones:
        if z.command in POLYGONS:
            inside = not polygon_outside(p, z.vertices)
        else:
            c_lat, c_lon = z.vertices[0][0] * 1e-7, z.vertices[0][1] * 1e-7
            d = _circle_distance_m(lat_e7 * 1e-7, lon_e7 * 1e-7, c_lat, c_lon)
            inside = d <= z.radius_m if z.command == CIRCLE_IN else d < z.radius_m
        if inside != z.inclusion:
            return True
    return False
