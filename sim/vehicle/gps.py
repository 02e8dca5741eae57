"""A GPS receiver model: white noise on a slowly drifting first-order Gauss-Markov bias, at
its own rate, with the accuracy figures (eph/epv) a receiver reports. Seeded.

It also carries the error of the autopilot's position estimate (`estimate_error`): an EKF fed
by this receiver converges to the truth plus the receiver's horizontal bias, but holds height
on its barometer, as PX4's EKF2 does by default (EKF2_HGT_REF: baro), so the vertical error is
the barometer's slow drift (0.2 m sd), not the receiver's vertical bias (1 m sd). Flying height
on the GPS's vertical bias moved the true altitude by metres over a flight (1.3 m instead of
3.5 m seen), which shrinks or widens the camera's footprint by as much."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geo import HomePosition


@dataclass(frozen=True)
class GpsConfig:
    rate_hz: float = 5.0
    sigma_h: float = 0.6  # m, white noise per horizontal axis
    sigma_v: float = 1.0
    bias_sigma_h: float = 0.7  # m, steady-state sd of the drifting bias
    bias_sigma_v: float = 1.0
    bias_tau_s: float = 60.0
    sigma_vel: float = 0.1  # m/s
    satellites: int = 12
    #: the autopilot holds height on a barometer (its drift: Gauss-Markov, sd and tau); False:
    #: on this receiver's vertical error, as before
    height_from_baro: bool = True
    baro_sigma_m: float = 0.2
    baro_tau_s: float = 60.0

    def __post_init__(self) -> None:
        if self.rate_hz <= 0 or self.bias_tau_s <= 0 or self.baro_tau_s <= 0:
            raise ValueError("rate_hz, bias_tau_s and baro_tau_s must be > 0")
        if min(self.sigma_h, self.sigma_v, self.bias_sigma_h, self.bias_sigma_v, self.sigma_vel, self.baro_sigma_m) < 0:
            raise ValueError("noise levels must be >= 0")


@dataclass(frozen=True)
class GpsFix:
    time_s: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    vel_ned: np.ndarray
    eph_m: float
    epv_m: float
    fix_type: int  # 3 = 3D
    satellites_visible: int


class GpsModel:
    def __init__(self, home: HomePosition, seed: int = 0, cfg: GpsConfig | None = None) -> None:
        self.home, self.cfg = home, cfg or GpsConfig()
        self.rng = np.random.default_rng([seed, 0x6905])
        c = self.cfg
        self.bias = self.rng.normal(0, [c.bias_sigma_h, c.bias_sigma_h, c.bias_sigma_v])
        # the barometer's own stream, so the receiver's is the same with or without it
        self._baro_rng = np.random.default_rng([seed, 0xBA20])
        self.baro = float(self._baro_rng.normal(0, c.baro_sigma_m))
        self._set_estimate_error()
        self._next = 0.0
        self._last_t: float | None = None
        # every fix draws from these; scales as arrays, made once (a list given to rng.normal is
        # converted on every call: 15 us of a 72 us fix, 5 fixes a second per vehicle)
        self._bias_sd = np.array([c.bias_sigma_h, c.bias_sigma_h, c.bias_sigma_v])
        self._noise_sd = np.array([c.sigma_h, c.sigma_h, c.sigma_v])
        self._period = 1.0 / c.rate_hz
        self._eph, self._epv = float(np.hypot(c.sigma_h, c.bias_sigma_h)), float(np.hypot(c.sigma_v, c.bias_sigma_v))
        # HomePosition.ned_to_geodetic's two denominators, computed as it computes them (per call)
        m, n = home.radii()
        self._km, self._kn = float(m + home.alt_m), float((n + home.alt_m) * np.cos(np.radians(home.lat_deg)))

    def _set_estimate_error(self) -> None:
        self._estimate_error = (np.array([self.bias[0], self.bias[1], self.baro]) if self.cfg.height_from_baro
                                else self.bias.copy())

    @property
    def estimate_error(self) -> np.ndarray:
        """The autopilot's position-estimate error (north, east, down): the receiver's bias
        horizontally, the barometer's drift vertically (see the module docstring). Read every
        tick: computed when the errors change (on a fix), not on every read."""
        return self._estimate_error

    @property
    def eph(self) -> float:
        return float(np.hypot(self.cfg.sigma_h, self.cfg.bias_sigma_h))

    @property
    def epv(self) -> float:
        return float(np.hypot(self.cfg.sigma_v, self.cfg.bias_sigma_v))

    def sample(self, time_s: float, position_ned: np.ndarray, velocity_ned: np.ndarray) -> GpsFix | None:
        """A fix when one is due at time_s, else None.

        The receiver's stream draws the bias step, the position noise and the velocity noise in
        that order, as three rng.normal calls did: one standard_normal draw of 9 (or 6), scaled
        (numpy's normal(0, s) is 0 + s * the same standard normal), the same numbers for a seed
        (tests/sim/vehicle/test_sensors.py keeps the three-call version and compares)."""
        if time_s + 1e-9 < self._next:
            return None
        c = self.cfg
        # plain floats on 3-vectors (numpy's per-call cost there is most of a fix): the same IEEE
        # products and sums in the same order, so the same numbers
        if self._last_t is not None:
            z = self.rng.standard_normal(9).tolist()
            dt = time_s - self._last_t
            a = float(np.exp(-dt / c.bias_tau_s))
            k = math.sqrt(1 - a * a)
            b0, b1, b2 = self.bias.tolist()
            sh, sv = c.bias_sigma_h * k, c.bias_sigma_v * k
            self.bias = np.array([a * b0 + z[0] * sh, a * b1 + z[1] * sh, a * b2 + z[2] * sv])
            ab = np.exp(-dt / c.baro_tau_s)
            self.baro = float(ab * self.baro + self._baro_rng.normal(0, c.baro_sigma_m * np.sqrt(1 - ab * ab)))
            self._set_estimate_error()
            z = z[3:]
        else:
            z = self.rng.standard_normal(6).tolist()
        self._last_t = time_s
        self._next = time_s + self._period
        p0, p1, p2 = np.asarray(position_ned, float).tolist()
        b0, b1, b2 = self.bias.tolist()
        nh, nv, nw = c.sigma_h, c.sigma_v, c.sigma_vel
        h = self.home  # HomePosition.ned_to_geodetic in floats (the same operations)
        lat = h.lat_deg + math.degrees((p0 + b0 + z[0] * nh) / self._km)
        lon = h.lon_deg + math.degrees((p1 + b1 + z[1] * nh) / self._kn)
        alt = h.alt_m - (p2 + b2 + z[2] * nv)
        v0, v1, v2 = np.asarray(velocity_ned, float).tolist()
        vel = np.array([v0 + z[3] * nw, v1 + z[4] * nw, v2 + z[5] * nw])
        return GpsFix(time_s, lat, lon, alt, vel, self._eph, self._epv, 3, c.satellites)
