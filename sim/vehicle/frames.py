"""The one conversion between PyBullet's world (ENU: x east, y north, z up; body FLU) and
the NED/FRD frames MAVLink speaks."""

from __future__ import annotations

import numpy as np


def enu_to_ned(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def ned_to_enu(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def enu_yaw_to_ned(yaw_enu: float) -> float:
    """Heading: ENU yaw is from east, counter-clockwise; NED yaw from north, clockwise."""
    return float((np.pi / 2 - yaw_enu + np.pi) % (2 * np.pi) - np.pi)


ned_yaw_to_enu = enu_yaw_to_ned  # the map is its own inverse


def rpy_flu_to_frd(rpy_enu: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) of a FLU body in ENU -> of the FRD body in NED."""
    r, p, y = rpy_enu
    return np.array([r, -p, enu_yaw_to_ned(y)])
