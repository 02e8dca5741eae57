"""GPS -> position posterior: a constant-velocity Kalman filter (filterpy) in local NED.

Why a filter at all: the policy acts per 2 m cell and a consumer GPS wanders by about a metre,
so raw fixes flicker across cell borders. The posterior (mean and covariance) feeds the
probabilistic visitation map, which spreads each visit over the cells it may have been in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter


@dataclass(frozen=True)
class EstimatorConfig:
    #: white-acceleration spectral density (m^2/s^3): how hard the airframe may manoeuvre
    accel_noise: float = 2.0
    #: floor on the GPS position standard deviation (m), used when eph is missing or optimistic
    min_sigma_h: float = 0.5
    min_sigma_v: float = 1.0
    #: a fix further than this many sigmas from the prediction is rejected as an outlier
    gate_sigmas: float = 6.0

    def __post_init__(self) -> None:
        if self.accel_noise <= 0 or self.min_sigma_h <= 0 or self.min_sigma_v <= 0:
            raise ValueError("accel_noise, min_sigma_h and min_sigma_v must be > 0")
        if self.gate_sigmas <= 0:
            raise ValueError("gate_sigmas must be > 0")


@dataclass(frozen=True)
class PositionPosterior:
    time_s: float
    mean_ned: np.ndarray  # (3,)
    cov_ned: np.ndarray  # (3, 3)
    velocity_ned: np.ndarray  # (3,)

    @property
    def horizontal_cov(self) -> np.ndarray:
        return self.cov_ned[:2, :2]


def transition(dt: float, accel_noise: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity F and white-acceleration Q for a step of dt seconds."""
    f = np.eye(6)
    f[:3, 3:] = np.eye(3) * dt
    q1 = Q_discrete_white_noise(dim=2, dt=dt, var=accel_noise)
    q = np.zeros((6, 6))
    for i in range(3):
        q[np.ix_([i, i + 3], [i, i + 3])] = q1
    return f, q


class GpsEstimator:
    """State x = [n, e, d, vn, ve, vd]; measurements are GPS positions in local NED."""

    def __init__(self, cfg: EstimatorConfig | None = None) -> None:
        self.cfg = cfg or EstimatorConfig()
        self.kf = KalmanFilter(dim_x=6, dim_z=3)
        self.kf.H = np.hstack([np.eye(3), np.zeros((3, 3))])
        self._t: float | None = None
        self.rejected = 0

    @property
    def initialised(self) -> bool:
        return self._t is not None

    def _predict_to(self, t: float) -> None:
        assert self._t is not None
        dt = t - self._t
        if dt < 0:
            raise ValueError(f"measurement time went backwards ({t} < {self._t})")
        if dt > 0:
            self.kf.F, self.kf.Q = transition(dt, self.cfg.accel_noise)
            self.kf.predict()
            self._t = t

    def update(
        self, t: float, position_ned: np.ndarray, eph: float | None = None, epv: float | None = None
    ) -> bool:
        """Fuse one GPS fix. Returns False when it was rejected by the innovation gate."""
        z = np.asarray(position_ned, dtype=float).reshape(3)
        if not np.all(np.isfinite(z)):
            raise ValueError(f"GPS position must be finite (got {z})")
        sh = max(self.cfg.min_sigma_h, eph or 0.0)
        sv = max(self.cfg.min_sigma_v, epv or 0.0)
        r = np.diag([sh**2, sh**2, sv**2])
        if self._t is None:
            self.kf.x = np.concatenate([z, np.zeros(3)])
            self.kf.P = np.diag([sh**2, sh**2, sv**2, 4.0, 4.0, 1.0])
            self._t = t
            return True
        self._predict_to(t)
        innov = z - self.kf.H @ self.kf.x
        s = self.kf.H @ self.kf.P @ self.kf.H.T + r
        if float(innov @ np.linalg.solve(s, innov)) > self.cfg.gate_sigmas**2 * 3:
            self.rejected += 1
            return False
        self.kf.update(z, R=r)
        return True

    def posterior(self, t: float | None = None) -> PositionPosterior:
        """The posterior now, or predicted forward to time t (without changing the filter)."""
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        x, p = self.kf.x.copy(), self.kf.P.copy()
        when = self._t
        if t is not None and t > self._t:
            f, q = transition(t - self._t, self.cfg.accel_noise)
            x, p, when = f @ x, f @ p @ f.T + q, t
        return PositionPosterior(when, x[:3].copy(), p[:3, :3].copy(), x[3:].copy())
