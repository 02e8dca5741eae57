"""WGS84 <-> local metres: the project's own local tangent plane, `HomePosition`.

Why not pyproj: every part of the stack (the SITL's GPS, the companion's estimator, the field
file's origin) turns NED into latitude/longitude with `sim.gridworld.geodesy.HomePosition`, a
tangent plane at the origin scaled by the ellipsoid's meridional and prime-vertical radii
there. Projecting the polygons with that same function means a vertex, a cell centre and a
setpoint the vehicle flies to agree exactly, in both directions (it is linear in latitude and
longitude, so the round trip is exact to rounding). Against the true ellipsoid it errs as the
square of the field's size (meridian convergence, ~ x * y * tan(lat) / R): measured against
Vincenty's geodesic distances between points of a square field with the origin at a corner,
at lat 51.45: 0.5 mm over 50 m, 8 mm over 200 m, 0.20 m over 1 km, which is why a field is
limited to 1 km a side (`MAX_EXTENT_M`). pyproj (an azimuthal equidistant projection) would be exact to the
millimetre further out, but would disagree with the rest of the stack by exactly that error
and brings the PROJ library with it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sim.gridworld.geodesy import HomePosition

from .shapes import LatLon

#: the largest field side, metres (the projection's error is 0.2 m there, a tenth of a cell)
MAX_EXTENT_M = 1000.0


class LocalProjection:
    """Local (north, east) metres about `origin` <-> (lat, lon) degrees."""

    def __init__(self, origin: HomePosition) -> None:
        self.origin = origin

    def to_ne(self, vertices: Sequence[LatLon]) -> np.ndarray:
        """(lat, lon) vertices -> (n, 2) (north, east) metres."""
        o = self.origin
        return np.array([o.geodetic_to_ned(la, lo, o.alt_m)[:2] for la, lo in vertices], dtype=np.float64)\
            .reshape(-1, 2)

    def to_latlon(self, ne: np.ndarray) -> list[LatLon]:
        """(n, 2) (north, east) metres -> (lat, lon) vertices."""
        return [self.origin.ned_to_geodetic(np.array([n, e, 0.0]))[:2] for n, e in np.asarray(ne).reshape(-1, 2)]
