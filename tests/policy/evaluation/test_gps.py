"""GPS noise in the grid-world evaluation: zero noise is the exact evaluation, the posterior is
a proper distribution that holds the truth, and the probabilistic belief copes with 1 m."""

import numpy as np
import pytest

from policy.baselines import make_policy
from policy.belief.gps import cell_probabilities_xy
from policy.evaluation.gps import GpsNoise, GpsTracker, evaluate_gps
from policy.evaluation.runner import evaluate
from sim.gridworld import DELTAS, GridConfig


def test_zero_noise_is_the_exact_evaluation():
    cfg = GridConfig()
    for name in ("belief", "frontier"):
        a = evaluate(make_policy(name, cfg), cfg, 60, 3, progress=False)
        b = evaluate_gps(make_policy(name, cfg), cfg, 60, 3, GpsNoise(sigma_m=0.0), progress=False)
        assert np.array_equal(a.moves, b.moves)


def test_cell_probabilities_match_a_monte_carlo_and_fold_onto_the_field():
    rng = np.random.default_rng(0)
    mean, sd = np.array([[0.3, 4.6]]), 0.8
    p = cell_probabilities_xy(mean, sd, 6, 7)[0]
    assert p.shape == (7, 6) and p.sum() == pytest.approx(1.0)
    s = mean[0] + rng.normal(0, sd, (1_000_000, 2))
    c = np.rint(s).astype(int)
    ok = (c[:, 0] >= 0) & (c[:, 0] < 6) & (c[:, 1] >= 0) & (c[:, 1] < 7)
    mc = np.zeros((7, 6))
    np.add.at(mc, (c[ok, 1], c[ok, 0]), 1.0)
    np.testing.assert_allclose(p, mc / mc.sum(), atol=2e-3)


def test_kalman_tracker_narrows_and_keeps_the_truth_likely():
    cfg = GridConfig()
    n = 400
    rng = np.random.default_rng(1)
    tr = GpsTracker(cfg, GpsNoise(sigma_m=1.0), n, rng)
    truth = rng.integers(2, 8, (n, 2)).astype(float)
    active = np.ones(n, bool)
    for _ in range(15):
        tr.fix(truth, active)
        a = rng.integers(0, 4, n)
        nxt = np.clip(truth + DELTAS[a], 0, 9)
        tr.moved(a, active & np.all(nxt == truth + DELTAS[a], axis=1))
        truth = np.where(np.all(nxt == truth + DELTAS[a], axis=1)[:, None], nxt, truth)
    tr.fix(truth, active)
    # one fix: sd 0.5 cell; fused with the moves (process 0.25 cell) it settles near 0.31
    assert np.sqrt(tr.var).max() < 0.7 * (1.0 / 2.0)
    views = np.zeros((n, 3, 3, 3), np.uint8)
    obs = tr.observation(views, np.zeros(n, np.int64), active)
    assert obs.position_prob.shape == (n, 10, 10)
    np.testing.assert_allclose(obs.position_prob.sum(axis=(1, 2)), 1.0, rtol=1e-5)
    t = truth.astype(int)
    assert (obs.positions == t).all(axis=1).mean() > 0.9


def test_probabilistic_belief_copes_with_one_metre_where_the_hard_map_fails():
    cfg = GridConfig()
    free = evaluate_gps(make_policy("belief", cfg), cfg, 60, 8, GpsNoise(sigma_m=0.0), progress=False)
    prob = evaluate_gps(make_policy("belief", cfg), cfg, 60, 8, GpsNoise(sigma_m=1.0), progress=False)
    assert prob.columns["success_pct"] == 100.0
    assert prob.moves.mean() < 1.3 * free.moves.mean()
    with pytest.raises(ValueError, match="static targets"):
        evaluate_gps(make_policy("belief", cfg), GridConfig(motion="herd", distribution="equidistant",
                                                            map_variant="spatiotemporal"), 5, 0, GpsNoise())
    with pytest.raises(ValueError, match="estimator"):
        GpsNoise(estimator="magic")
