"""PX4's simple geofence: a cylinder around home (GF_MAX_HOR_DIST, GF_MAX_VER_DIST)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Geofence:
    max_horizontal_m: float = 100.0
    max_altitude_m: float = 30.0

    def allows(self, ned: np.ndarray) -> bool:
        return bool(np.hypot(ned[0], ned[1]) <= self.max_horizontal_m and -ned[2] <= self.max_altitude_m)

    def clamp(self, ned: np.ndarray, margin_m: float = 1.0) -> np.ndarray:
        """The point nearest `ned` at least `margin_m` inside the fence."""
        out = np.asarray(ned, dtype=float).copy()
        r, r_max = float(np.hypot(out[0], out[1])), max(self.max_horizontal_m - margin_m, 0.0)
        if r > r_max:
            out[:2] *= r_max / r
        out[2] = max(out[2], -max(self.max_altitude_m - margin_m, 0.5))
        return out
