"""GPS -> position posterior: a Gaussian sum of Kalman filters (filterpy's noise model) in local
NED whose state carries the receiver's slowly drifting bias next to position and velocity.

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

#: simulated seconds within which two stamps are one instant (see _predict_to)
TIME_EPS_S = 1e-6

#: an uninformative prior variance (m^2) on position before the first fix
PRIOR_VAR = 1e4
#: Gaussian-sum housekeeping: components weighing under PRUNE_W of the likeliest are dropped;
#: two whose horizontal positions agree within MERGE_SIGMAS (their covariances summed) are one
#: hypothesis and merged; at most MAX_COMPONENTS are kept (the closest pairs merged first)
PRUNE_W = 1e-3
MERGE_SIGMAS = 2.0
MAX_COMPONENTS = 8
#: position + bias (north, east): what the receiver and the autopilot's estimate measure
_READING_H = np.zeros((2, 9))
_READING_H[[0, 1], [0, 1]] = 1.0
_READING_H[[0, 1], [6, 7]] = 1.0


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
    """State x = [n, e, d, vn, ve, vd, bn, be, bd]; a fix measures position + bias.

    The posterior is a Gaussian sum: a bank of Kalman filters (weight, mean, covariance), one
    per hypothesis of which lattice point the camera truly is at. GPS fixes and plain position
    measurements update every component (and weigh them by how well each predicted them); a
    target seen on *some* cell's centre splits each component into one per candidate cell
    (`observe_position_mixture`). Components that come to the same hypothesis are merged
    (moment matching), the unlikely pruned. Why a sum and not one Gaussian: the lattice is
    ambiguous by whole cells, and every later sighting is ambiguous the same way. Collapsing
    each sighting to one Gaussian (moment matching) counted that same ambiguity again at every
    cow: a posterior a cell off hardened to 0.2 m sd in four sightings (held-out flight seed
    43: NEES 147, the last cow found at move 89 against 36 in the grid world). With the sum
    the odds of the two frames stay what the evidence makes them: only what tells them apart
    (a cow at the field's edge, a found cow's known cell, the bias's own dynamics) moves them.
    With one component it is the plain Kalman filter."""

    def __init__(self, cfg: EstimatorConfig | None = None) -> None:
        self.cfg = cfg or EstimatorConfig()
        #: the components: log weights (n,), means (n, 9), covariances (n, 9, 9)
        self._logw = np.zeros(1)
        self._x = np.zeros((1, 9))
        self._p = np.eye(9)[None] * PRIOR_VAR
        self._h = np.hstack([np.eye(3), np.zeros((3, 3)), np.eye(3)])
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

    @property
    def n_components(self) -> int:
        return len(self._logw)

    @property
    def weights(self) -> np.ndarray:
        w = np.exp(self._logw - self._logw.max())
        return w / w.sum()

    @property
    def mean(self) -> np.ndarray:
        """The full state's mean (9,) over the components."""
        return self.weights @ self._x

    @property
    def cov(self) -> np.ndarray:
        """The full state's covariance (9, 9) over the components (their own plus the spread
        of their means)."""
        return _moments(self.weights, self._x, self._p)[1]

    def set_state(self, mean: np.ndarray, cov: np.ndarray) -> None:
        """Replace the posterior by one Gaussian (mean (9,), covariance (9, 9))."""
        self._logw = np.zeros(1)
        self._x = np.asarray(mean, dtype=float).reshape(1, 9).copy()
        self._p = np.asarray(cov, dtype=float).reshape(1, 9, 9).copy()

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

    def _predicted(self, t: float | None) -> tuple[np.ndarray, np.ndarray]:
        """The components' means and covariances predicted to time t (without changing them)."""
        assert self._t is not None
        if t is None or t <= self._t:
            return self._x, self._p
        f, q = self._step(t - self._t)
        return self._x @ f.T, f @ self._p @ f.T + q

    def _predict_to(self, t: float) -> None:
        assert self._t is not None
        dt = t - self._t
        # stamps come rounded through microseconds (GPS time_usec, the camera's PNG stamp) while
        # the schedule sums periods in floats: within TIME_EPS_S they are the same instant
        # (PX4 on our world, 4 flights in 20: 118.19999999999999 after 118.2)
        if dt < -TIME_EPS_S:
            raise ValueError(f"measurement time went backwards ({t} < {self._t})")
        if dt > 0:
            self._x, self._p = self._predicted(t)
            self._t = t

    def _linear_update(self, h: np.ndarray, z: np.ndarray, r: np.ndarray) -> None:
        """Fuse z = h x + v, v ~ N(0, r) into every component (Joseph form), weighing each by
        how well it predicted z."""
        p = self._p
        s = h @ p @ h.T + r  # (n, m, m)
        s_inv = np.linalg.inv(s)
        k = p @ h.T @ s_inv  # (n, 9, m)
        innov = z - self._x @ h.T  # (n, m)
        self._x = self._x + np.einsum("nij,nj->ni", k, innov)
        i_kh = np.eye(9) - k @ h
        self._p = i_kh @ p @ np.swapaxes(i_kh, 1, 2) + k @ r @ np.swapaxes(k, 1, 2)
        if len(self._logw) > 1:
            self._logw = self._logw - 0.5 * (np.einsum("ni,nij,nj->n", innov, s_inv, innov)
                                             + np.log(np.linalg.det(s)))
            self._logw -= self._logw.max()

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
            x0 = np.zeros(9)
            x0[:3] = z
            self.set_state(x0, np.diag([PRIOR_VAR] * 3 + [4.0, 4.0, 1.0] + list(bias)))
            self._linear_update(self._h, z, r)
            self._t = t
            return True
        self._predict_to(t)
        mean, cov = _moments(self.weights, self._x, self._p)
        innov = z - self._h @ mean
        s = self._h @ cov @ self._h.T + r
        if float(innov @ np.linalg.solve(s, innov)) > self.cfg.gate_sigmas**2 * 3:
            self.rejected += 1
            return False
        self._linear_update(self._h, z, r)
        return True

    def _measurement_at(self, t: float, z: np.ndarray, sd_m: float, what: str) -> np.ndarray:
        """Check a GPS-free measurement (finite, sd > 0, after the first fix) and predict the
        filter to its time t; times before the last fused fix are taken as now (the filter does
        not run backwards). Returns z as floats."""
        z = np.asarray(z, dtype=float).reshape(-1)
        if not len(z) or not np.all(np.isfinite(z)) or not (math.isfinite(sd_m) and sd_m > 0):
            raise ValueError(f"{what} must be finite and sd > 0 (got {z}, {sd_m})")
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        if t > self._t:
            self._predict_to(t)
        return z

    def observe_position(self, t: float, position: np.ndarray, sd_m: float, axes: tuple[int, ...] = (0, 1)) -> None:
        """Fuse a measurement of the true position along `axes` (0 north, 1 east, 2 down; no GPS
        bias in it): the vehicle on the ground at its surveyed launch point, a target seen at a
        known offset from the camera standing on a cell's centre, the camera's height from a
        target's size. It is what makes the bias observable: GPS alone cannot tell the bias from
        the position. Times before the last fused fix are taken as now (the filter does not run
        backwards)."""
        z = self._measurement_at(t, np.asarray(position, dtype=float).reshape(len(axes)), sd_m, "position")
        m = len(axes)
        h = np.zeros((m, 9))
        h[np.arange(m), list(axes)] = 1.0
        self._linear_update(h, z, np.eye(m) * sd_m**2)
        self._reduce()

    def observe_along(self, t: float, direction_ne: np.ndarray, value: float, sd_m: float) -> None:
        """Fuse a measurement of the true position's component along a horizontal unit direction
        (north, east; no GPS bias in it): a polygon field's edge at an angle to the grid, seen in
        a frame, says how far the camera is from its line, and nothing along it. Times before
        the last fused fix are taken as now."""
        u = _unit(direction_ne)
        z = self._measurement_at(t, np.array([value]), sd_m, "position along a direction")
        h = np.zeros((1, 9))
        h[0, :2] = u
        self._linear_update(h, z, np.eye(1) * sd_m**2)
        self._reduce()

    def observe_reading(self, t: float, reading_ne: np.ndarray, sd_m: float) -> None:
        """Fuse the autopilot's own position estimate (north, east) as a measurement of
        position + bias: its EKF smooths the receiver's white noise out with the inertial
        sensors, so what is left of its error is the bias (the state's), and the true
        position's mean is then that reading less the bias, not the few fixes' average (which
        kept ~0.6 m of white noise: a cow 0.95 m off the nadir then fitted the wrong cell, held-
        out flight seed 43). Times before the last fused fix are taken as now."""
        z = self._measurement_at(t, np.asarray(reading_ne, dtype=float).reshape(2), sd_m, "reading")
        self._linear_update(_READING_H, z, np.eye(2) * sd_m**2)

    def observe_position_mixture(self, t: float, axis: int, candidates: np.ndarray, sd_m: float) -> np.ndarray:
        """Fuse a measurement of the true position along one axis that is one of several
        candidates (a target seen at a known offset from the camera stands on *some* cell's
        centre: the camera is at one lattice point less the offset), each as likely a priori.
        The exact posterior is a Gaussian sum: each component splits into one per candidate,
        weighed by how well the candidate fits it; components that land on the same hypothesis
        are merged and the unlikely pruned (`_reduce`). Returns the candidates' weights."""
        z = self._measurement_at(t, candidates, sd_m, "candidates")
        n, m = len(self._logw), len(z)
        p = self._p
        s = p[:, axis, axis] + sd_m**2  # (n,)
        k = p[:, :, axis] / s[:, None]  # (n, 9)
        innov = z[None, :] - self._x[:, axis, None]  # (n, m)
        x = self._x[:, None, :] + k[:, None, :] * innov[:, :, None]  # (n, m, 9)
        i_kh = np.broadcast_to(np.eye(9), (n, 9, 9)).copy()
        i_kh[:, :, axis] -= k
        pc = i_kh @ p @ np.swapaxes(i_kh, 1, 2) + k[:, :, None] * k[:, None, :] * sd_m**2  # (n, 9, 9)
        logw = self._logw[:, None] - 0.5 * (innov**2 / s[:, None] + np.log(s)[:, None])  # (n, m)
        self._logw = (logw - logw.max()).reshape(-1)
        self._x = x.reshape(n * m, 9)
        self._p = np.repeat(pc, m, axis=0)
        w = np.exp(logw - logw.max())
        self._reduce()
        return w.sum(axis=0) / w.sum()

    def observe_bound(self, t: float, axis: int, bound: float, below: bool, sd_m: float,
                      miss: float = 0.02) -> None:
        """Fuse that the true position along `axis` is below (or above) `bound`, give or take
        sd_m: something that would be seen from beyond it is not in view (the field's edge).
        The likelihood is miss + (1 - miss) Phi((bound - x) / sd_m) (`miss`: the chance the
        evidence is wrong, the edge there but not found). Each component is weighed by how
        likely it makes the evidence and takes the exact mean and variance of its posterior
        along the axis (a probit update, moment matched), carried to the rest of the state by
        its correlations as a Kalman update would. On a Gaussian sum it decides between the
        lattice's hypotheses (a frame a cell off would have had the border in view); on each
        component it trims the side the evidence rules out."""
        from scipy.stats import norm

        self._measurement_at(t, np.array([bound]), sd_m, "bound")
        sign = 1.0 if below else -1.0
        mu, v = self._x[:, axis], self._p[:, axis, axis]
        root = np.sqrt(v + sd_m**2)
        u = sign * (bound - mu) / root
        log_phi_cdf = norm.logcdf(u)
        lam = np.exp(norm.logpdf(u) - log_phi_cdf)  # phi(u) / Phi(u), stable far in the tail
        mean_t = mu - sign * v * lam / root  # the moments under the probit likelihood alone
        var_t = v - v**2 * lam * (u + lam) / root**2
        w_miss, w_hit = miss, (1.0 - miss) * np.exp(log_phi_cdf)
        z = w_miss + w_hit
        mean = (w_miss * mu + w_hit * mean_t) / z
        var = np.maximum((w_miss * (v + mu**2) + w_hit * (var_t + mean_t**2)) / z - mean**2, 1e-12)
        g = self._p[:, :, axis] / v[:, None]  # (n, 9): how the state moves with the axis
        self._x = self._x + g * (mean - mu)[:, None]
        self._p = self._p + g[:, :, None] * g[:, None, :] * (var - v)[:, None, None]
        self._logw = self._logw + np.log(z)
        self._logw -= self._logw.max()
        self._reduce()

    def _reduce(self) -> None:
        """Prune components under PRUNE_W of the total and merge (moment matching) those whose
        positions agree within MERGE_SIGMAS (the same lattice hypothesis reached by two paths),
        then the closest pairs while more than MAX_COMPONENTS remain."""
        w = self.weights
        keep = w >= PRUNE_W * w.max()
        self._logw, self._x, self._p = np.log(w[keep]), self._x[keep], self._p[keep]
        while len(self._logw) > 1:
            w = self.weights
            d = self._x[:, None, :2] - self._x[None, :, :2]  # (n, n, 2) horizontal position
            c = self._p[:, None, :2, :2] + self._p[None, :, :2, :2]
            d2 = np.einsum("abi,abij,abj->ab", d, np.linalg.inv(c), d)
            d2[np.diag_indices(len(w))] = np.inf
            i, j = np.unravel_index(int(np.argmin(d2)), d2.shape)
            if d2[i, j] > MERGE_SIGMAS**2 and len(w) <= MAX_COMPONENTS:
                break
            ww = w[[i, j]]
            mean, cov = _moments(ww / ww.sum(), self._x[[i, j]], self._p[[i, j]])
            rest = [q for q in range(len(w)) if q not in (i, j)]
            self._logw = np.concatenate([np.log(w[rest]), [math.log(ww.sum())]])
            self._x = np.concatenate([self._x[rest], mean[None]])
            self._p = np.concatenate([self._p[rest], cov[None]])
        self._logw -= self._logw.max()

    def doubt_split(self, sd_m: float, axes: tuple[int, ...] = (0, 1)) -> None:
        """Add sd_m^2 of doubt to how the GPS reading splits into position and bias (north,
        east), keeping the doubt on their sum (what the receiver measures) as it is: a position
        measurement that contradicts the posterior (a target seen off the field) then moves the
        estimate to it instead of being averaged with a wrong belief."""
        v = sd_m**2
        p = self._p
        for i in axes:
            p[:, i, i] += v
            p[:, i + 6, i + 6] += v
            p[:, i, i + 6] -= v
            p[:, i + 6, i] -= v

    def doubt_split_along(self, sd_m: float, direction_ne: np.ndarray) -> None:
        """`doubt_split` along a horizontal unit direction (north, east): an edge of the field at
        an angle that contradicts the posterior doubts the split across that edge only."""
        u = _unit(direction_ne)
        d = sd_m**2 * np.outer(u, u)
        p = self._p
        p[:, :2, :2] += d
        p[:, 6:8, 6:8] += d
        p[:, :2, 6:8] -= d
        p[:, 6:8, :2] -= d

    @property
    def bias_ned(self) -> np.ndarray:
        """The estimated GPS bias (north, east, down): what the autopilot's own GPS-fed estimate
        is off by, so a setpoint shifted by it puts the vehicle truly where it is meant to be.
        The most probable component's: the camera is flown over the cell its likeliest frame
        says, not between two frames' cells (where neither sees a target under it)."""
        if self._t is None:
            return np.zeros(3)
        return self._x[int(np.argmax(self._logw)), 6:9].copy()

    def components(self, t: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The posterior's components at time t: weights (n,), position means (n, 3) and
        covariances (n, 3, 3), in `component_bias`' order."""
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        x, p = self._predicted(t)
        return self.weights, x[:, :3].copy(), p[:, :3, :3].copy()

    def component_bias(self) -> np.ndarray:
        """(n, 3): each component's bias mean (north, east, down), in `components`' order."""
        return self._x[:, 6:9].copy()

    def reading_ne(self, t: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Position + bias (north, east): where the receiver (and the autopilot that flies on
        it) puts the vehicle, with its variance per axis. GPS measures this sum directly, so it
        stays well known (~0.15 m) whatever the split into position and bias; two readings
        of one spot differ only by the bias's drift in between (`drift_var`)."""
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        x, p = _moments(self.weights, *self._predicted(t))
        return _READING_H @ x, np.diag(_READING_H @ p @ _READING_H.T).copy()

    def drift_var(self, dt: float) -> np.ndarray:
        """Variance (north, east) of the bias's change over dt seconds (Gauss-Markov)."""
        return 2.0 * self._bias_var[:2] * (1.0 - math.exp(-abs(dt) / self.cfg.bias_tau_s))

    def posterior(self, t: float | None = None) -> PositionPosterior:
        """The posterior of the true position now, or predicted forward to time t (without
        changing the filter): the components' mean and covariance."""
        if self._t is None:
            raise RuntimeError("no GPS fix fused yet")
        x, p = _moments(self.weights, *self._predicted(t))
        when = self._t if t is None or t <= self._t else t
        return PositionPosterior(when, x[:3].copy(), p[:3, :3].copy(), x[3:6].copy())


def _moments(w: np.ndarray, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of a Gaussian sum (weights w summing to 1, means x, covariances p)."""
    if len(w) == 1:
        return x[0].copy(), p[0].copy()
    mean = w @ x
    d = x - mean
    return mean, np.einsum("n,nij->ij", w, p) + np.einsum("n,ni,nj->ij", w, d, d)


def _unit(direction_ne: np.ndarray) -> np.ndarray:
    """(north, east) -> the same direction at unit length; a zero or non-finite one is refused."""
    u = np.asarray(direction_ne, dtype=float).reshape(2)
    n = float(np.hypot(*u))
    if not (math.isfinite(n) and n > 1e-9):
        raise ValueError(f"a direction must be a finite, non-zero (north, east) vector (got {u})")
    return u / n
