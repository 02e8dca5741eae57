"""GPS -> position posterior: a Kalman filter (filterpy) in local NED whose state carries the
receiver's slowly drifting bias next to position and velocity.

Why a filter at all: the policy acts per 2 m cell and a consumer GPS wanders by about a metre,
so raw fixes flicker across cell borders. The posterior (mean and covariance) feeds the
probabilistic visitation map, which spreads each visit over the cells it may have been in.

Why the bias is in the state: a GPS error is mostly a first-order Gauss-Markov bias (minutes
of correlation) plus a little white noise. A filter that treats the whole error as white
averages fixes as if they were independent and shrinks its covariance far below the real
error (mean NEES 4.4 against the simulator's truth where 2 is expected). With the bias as
state b (b' = a b + q, a = exp(-dt / tau), Var q = sigma_b^2 (1 - a^2)) and z = p + b + w the
position covariance settles near the bias variance, which is the honest answer: GPS alone
cannot tell the bias from the position. The receiver reports only its total accuracy (eph);
the bias's share of that variance and its correlation time are the receiver's error model
(EstimatorConfig), as a datasheet or a static survey would give them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

#: an uninformative prior variance (m^2) on position before the first fix
PRIOR_VAR = 1e4


@dataclass(frozen=True)
class EstimatorConfig:
    #: white-acceleration spectral density (m^2/s^3): how hard the airframe may manoeuvre
    accel_noise: float = 0.5
    #: floor on the GPS position standard deviation (m), used when eph is missing or optimistic
    min_sigma_h: float = 0.5
    min_sigma_v: float = 1.0
    #: a fix further than this many sigmas from the prediction is rejected as an outlier
    gate_sigmas: float = 6.0
    #: share of the reported GPS variance that is the drifting bias, not white noise (the
    #: simulated receiver: bias 0.7 m, white 0.6 m -> 0.49 / 0.85); 0 gives the white-only filter
    bias_share: float = 0.49 / 0.85
    #: correlation time of the bias (s)
    bias_tau_s: float = 60.0

    def __post_init__(self) -> None:
        if self.accel_noise <= 0 or self.min_sigma_h <= 0 or self.min_sigma_v <= 0:
            raise ValueError("accel_noise, min_sigma_h and min_sigma_v must be > 0")
        if self.gate_sigmas <= 0:
            raise ValueError("gate_sigmas must be > 0")
        if not 0.0 <= self.bias_share < 1.0:
            raise ValueError(f"bias_share must be in [0, 1) (got {self.bias_share})")
        if self.bias_tau_s <= 0:
            raise ValueError(f"bias_tau_s must be > 0 (got {self.bias_tau_s})")


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
    """Constant-velocity F and white-acceleration Q (6 x 6) for a step of dt seconds."""
    f = np.eye(6)
    f[:3, 3:] = np.eye(3) * dt
    q1 = Q_discrete_white_noise(dim=2, dt=dt, var=accel_noise)
    q = np.zeros((6, 6))
    for i in range(3):
        q[np.ix_([i, i + 3], [i, i + 3])] = q1
    return f, q


class GpsEstimator:
    """State x = [n, e, d, vn, ve, vd, bn, be, bd]; a fix measures position + bias."""

    def __init__(self, cfg: EstimatorConfig | None = None) -> None:
        self.cfg = cfg or EstimatorConfig()
        self.kf = KalmanFilter(dim_x=9, dim_z=3)
        self.kf.H = np.hstack([np.eye(3), np.zeros((3, 3)), np.eye(3)])
        self._t: float | None = None
        self._bias_var = np.zeros(3)  # steady-state bias variance per axis (from the last eph)
        self.rejected = 0

    @property
    def initialised(self) -> bool:
        return self._t is not None

    @property
    def time_s(self) -> float | None:
        """Time of the last fused fix."""
        return self._t

    def _split(self, eph: float | None, epv: float | None) -> tuple[np.ndarray, np.ndarray]:
        """Reported accuracies -> (white variance, bias variance) per axis (n, e, d)."""
        sh = max(self.cfg.min_sigma_h, eph or 0.0)
        sv = max(self.cfg.min_sigma_v, epv or 0.0)
        total = np.array([sh**2, sh**2, sv**2])
        return total * (1.0 - self.cfg.bias_share), total * self.cfg.bias_share

    def _step(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        f6, q6 = transition(dt, self.cfg.accel_noise)
        a = np.exp(-dt / self.cfg.bias_tau_s)
        f, q = np.eye(9), np.zeros((9, 9))
        f[:6, :6], q[:6, :6] = f6, q6
        f[6:, 6:] = np.eye(3) * a
        q[6:, 6:] = np.diag(self._bias_var * (1.0 - a * a))
        return f, q

    def _predict_to(self, t: float) -> None:
        assert self._t is not None
        dt = t - self._t
        if dt < 0:
            raise ValueError(f"measurement time went backwards ({t} < {self._t})")
        if dt > 0:
            self.kf.F, self.kf.Q = self._step(dt)
            self.kf.predict()
            self._t = t

    def update(
        self, t: float, position_ned: np.ndarray, eph: float | None = None, epv: float | None = None
    ) -> bool:
        """Fuse one GPS fix. Returns False when it was rejected by the innovation gate."""
        z = np.asarray(position_ned, dtype=float).reshape(3)
        if not np.all(np.isfinite(z)):
            raise ValueError(f"GPS position must be finite (got {z})")
        white, bias = self._split(eph, epv)
        self._bias_var = bias
        r = np.diag(white)
        if self._t is None:
            # an uninformative position prior and the bias's steady state, then the first fix
            self.kf.x = np.zeros(9)
            self.kf.x[:3] = z
            self.kf.P = np.diag([PRIOR_VAR] * 3 + [4.0, 4.0, 1.0] + list(bias))
            self.kf.update(z, R=r)
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

    def observe_position(self, t: float, position: np.ndarray, sd_m: float, axes: tuple[int, ...] = (0, 1)) -> None:
        """Fuse a measurement of the true position along `axes` (0 north, 1 east, 2 down; no GPS
        bias in it): the vehicle on the ground at its surveyed launch point, a target seen at a
        known offset from the camera standing on a cell's centre, the camera's height from a
        target's size. It is what makes the bias observable: GPS alone cannot tell the bias from
        the position. Times before the last fused fix are taken as now (the filter does not run
        backwards)."""
        z = np.asarray(position, dtype=float).reshape(len(axes))
        if not np.all(np.isfinite(z)) or not (math.isfinite(sd_m) and sd_m > 0):
            raise ValueError(f"position must be finite and sd > 0 (got {z}, {sd_m})")
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        if t > self._t:
            self._predict_to(t)
        m = len(axes)
        h = np.zeros((m, 9))
        h[np.arange(m), list(axes)] = 1.0
        r = np.eye(m) * sd_m**2
        x, p = self.kf.x, self.kf.P
        k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
        self.kf.x = x + k @ (z - h @ x)
        i_kh = np.eye(9) - k @ h
        self.kf.P = i_kh @ p @ i_kh.T + k @ r @ k.T  # Joseph form

    def observe_position_mixture(self, t: float, axis: int, candidates: np.ndarray, sd_m: float) -> np.ndarray:
        """Fuse a measurement of the true position along one axis that is one of several
        candidates (a target seen at a known offset from the camera stands on *some* cell's
        centre: the camera is at one lattice point less the offset), each as likely a priori.
        The exact posterior is a Gaussian mixture, one component per candidate weighed by how
        well it fits the prior; it is collapsed to its mean and covariance (moment matching, as
        probabilistic data association does), so an ambiguous sighting tightens the posterior
        only as far as its odds allow and never locks it onto one wrong cell. Returns the
        candidates' weights."""
        z = np.asarray(candidates, dtype=float).reshape(-1)
        if not len(z) or not np.all(np.isfinite(z)) or not (math.isfinite(sd_m) and sd_m > 0):
            raise ValueError(f"candidates must be finite and sd > 0 (got {z}, {sd_m})")
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        if t > self._t:
            self._predict_to(t)
        x, p = self.kf.x, self.kf.P
        s = float(p[axis, axis]) + sd_m**2
        k = p[:, axis] / s
        innov = z - x[axis]
        w = np.exp(-(innov**2 - (innov**2).min()) / (2.0 * s))
        w /= w.sum()
        mean_innov = float(w @ innov)
        spread = float(w @ innov**2) - mean_innov**2  # variance of the innovation over the candidates
        self.kf.x = x + k * mean_innov
        # each component's covariance (the same for all: one measurement model), Joseph form,
        # plus the spread of the components' means about the mixture's
        i_kh = np.eye(9)
        i_kh[:, axis] -= k
        self.kf.P = i_kh @ p @ i_kh.T + np.outer(k, k) * (sd_m**2 + spread)
        return w

    def doubt_split(self, sd_m: float, axes: tuple[int, ...] = (0, 1)) -> None:
        """Add sd_m^2 of doubt to how the GPS reading splits into position and bias (north,
        east), keeping the doubt on their sum (what the receiver measures) as it is: a position
        measurement that contradicts the posterior (a target seen off the field) then moves the
        estimate to it instead of being averaged with a wrong belief."""
        v = sd_m**2
        p = self.kf.P
        for i in axes:
            p[i, i] += v
            p[i + 6, i + 6] += v
            p[i, i + 6] -= v
            p[i + 6, i] -= v

    @property
    def bias_ned(self) -> np.ndarray:
        """The estimated GPS bias (north, east, down): what the autopilot's own GPS-fed estimate
        is off by, so a setpoint shifted by it puts the vehicle truly where it is meant to be."""
        return self.kf.x[6:9].copy() if self._t is not None else np.zeros(3)

    def reading_ne(self, t: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Position + bias (north, east): where the receiver (and the autopilot that flies on
        it) puts the vehicle, with its variance per axis. GPS measures this sum directly, so it
        stays well known (~0.15 m) whatever the split into position and bias; two readings
        of one spot differ only by the bias's drift in between (`drift_var`)."""
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        x, p = self.kf.x, self.kf.P
        if t is not None and t > self._t:
            f, q = self._step(t - self._t)
            x, p = f @ x, f @ p @ f.T + q
        h = np.zeros((2, 9))
        h[[0, 1], [0, 1]] = 1.0
        h[[0, 1], [6, 7]] = 1.0
        return h @ x, np.diag(h @ p @ h.T).copy()

    def drift_var(self, dt: float) -> np.ndarray:
        """Variance (north, east) of the bias's change over dt seconds (Gauss-Markov)."""
        return 2.0 * self._bias_var[:2] * (1.0 - math.exp(-abs(dt) / self.cfg.bias_tau_s))

    def posterior(self, t: float | None = None) -> PositionPosterior:
        """The posterior of the true position now, or predicted forward to time t (without
        changing the filter)."""
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        x, p = self.kf.x.copy(), self.kf.P.copy()
        when = self._t
        if t is not None and t > self._t:
            f, q = self._step(t - self._t)
            x, p, when = f @ x, f @ p @ f.T + q, t
        return PositionPosterior(when, x[:3].copy(), p[:3, :3].copy(), x[3:6].copy())
