import numpy as np
import pytest

from autopilot_bridge import EstimatorConfig, GpsEstimator


def _fly(seed: int, sigma: float = 1.0, n: int = 300, dt: float = 0.2):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    truth = np.stack([2.0 * t, np.sin(t / 5) * 10, -3.5 + 0 * t], axis=1)
    meas = truth + rng.normal(0, [sigma, sigma, 1.5], size=truth.shape)
    return t, truth, meas


def test_filter_beats_raw_gps_and_is_consistent() -> None:
    t, truth, meas = _fly(0)
    est = GpsEstimator()
    errs, nees = [], []
    for ti, z, x in zip(t, meas, truth, strict=True):
        est.update(ti, z, eph=1.0, epv=1.5)
        post = est.posterior()
        e = post.mean_ned[:2] - x[:2]
        errs.append(np.linalg.norm(e))
        nees.append(e @ np.linalg.solve(post.horizontal_cov, e))
    raw = np.linalg.norm(meas[50:, :2] - truth[50:, :2], axis=1).mean()
    assert np.mean(errs[50:]) < 0.7 * raw
    # normalised estimation error squared: ~2 for a consistent 2-D posterior
    assert 0.5 < np.mean(nees[50:]) < 6.0


def test_outlier_is_gated_and_counted() -> None:
    t, _, meas = _fly(1)
    est = GpsEstimator()
    for ti, z in zip(t[:100], meas[:100], strict=True):
        est.update(ti, z, eph=1.0)
    before = est.posterior().mean_ned.copy()
    assert not est.update(t[100], meas[100] + np.array([80.0, 0, 0]), eph=1.0)
    assert est.rejected == 1
    assert np.linalg.norm(est.posterior().mean_ned - before) < 2.0


def test_prediction_grows_uncertainty() -> None:
    est = GpsEstimator()
    est.update(0.0, np.zeros(3), eph=1.0)
    est.update(0.2, np.zeros(3), eph=1.0)
    now = est.posterior()
    later = est.posterior(t=5.0)
    assert np.trace(later.horizontal_cov) > np.trace(now.horizontal_cov)


def test_bad_input_is_a_clear_error() -> None:
    est = GpsEstimator()
    with pytest.raises(RuntimeError):
        est.posterior()
    est.update(1.0, np.zeros(3))
    with pytest.raises(ValueError, match="backwards"):
        est.update(0.5, np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        est.update(2.0, np.array([np.nan, 0, 0]))
    with pytest.raises(ValueError):
        EstimatorConfig(accel_noise=0)
