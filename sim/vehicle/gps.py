"""A GPS receiver model: white noise on a slowly drifting first-order Gauss-Markov bias, at
its own rate, with the accuracy figures (eph/epv) a receiver reports. Seeded.

It also carries the error of the autopilot's position estimate (`estimate_error`): an EKF fed
by this receiver converges to the truth plus the receiver's horizontal bias, but holds height
on its barometer, as PX4's EKF2 does by default (EKF2_HGT_REF: baro), so the vertical error is
the barometer's slow drift (0.2 m sd), not the receiver's vertical bias (1 m sd). Flying height
on the GPS's vertical bias moved the true altitude by metres over a flight (1.3 m instead of
3.5 m seen), which shrinks or widens the camera's footprint by as much."""

from __future__ import annotations

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
        """A fix when one is due at time_s, else None."""
        if time_s + 1e-9 < self._next:
            return None
        c = self.cfg
        if self._last_t is not None:
            dt = time_s - self._last_t
            a = np.exp(-dt / c.bias_tau_s)
            sd = np.array([c.bias_sigma_h, c.bias_sigma_h, c.bias_sigma_v]) * np.sqrt(1 - a * a)
            self.bias = a * self.bias + self.rng.normal(0, sd)
            ab = np.exp(-dt / c.baro_tau_s)
            self.baro = float(ab * self.baro + self._baro_rng.normal(0, c.baro_sigma_m * np.sqrt(1 - ab * ab)))
            self._set_estimate_error()
        self._last_t = time_s
        self._next = time_s + 1.0 / c.rate_hz
        noisy = np.asarray(position_ned, float) + self.bias + self.rng.normal(0, [c.sigma_h, c.sigma_h, c.sigma_v])
        lat, lon, alt = self.home.ned_to_geodetic(noisy)
        vel = np.asarray(velocity_ned, float) + self.rng.normal(0, c.sigma_vel, 3)
        return GpsFix(time_s, lat, lon, alt, vel, self.eph, self.epv, 3, c.satellites)
