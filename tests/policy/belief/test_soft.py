"""The belief under imperfect detection (policy.belief.soft): exact where the view is perfect,
a miss and a sighting as the Bayes factors of the detection table."""

from __future__ import annotations

import numpy as np
import pytest

from policy.base import Observation, observe
from policy.baselines import make_policy
from policy.belief import BeliefState
from sim.gridworld import BatchGridWorld, DetectionTable, GridConfig, sample_episodes

TABLE = DetectionTable(((1, 1), (0.95, 0.9, 0.8), (0.85, 0.75, 0.6, 0.45)), (0, 0.002, 0.005))


def test_perfect_table_at_level_one_is_the_exact_belief():
    """A perfect two-level table flown at level 1 only: the soft update gives the exact
    (perfect-view) belief's numbers, on the same episodes and moves."""
    c1, c2 = GridConfig(), GridConfig(levels=2, detection=DetectionTable.perfect(2))
    w1, w2 = BatchGridWorld(sample_episodes(c1, 30, 3), 3), BatchGridWorld(sample_episodes(c2, 30, 3), 3)
    b1, b2 = BeliefState(c1, 30), BeliefState(c2, 30)
    assert b1.soft is None and b2.soft is not None
    pol = make_policy("lawnmower")
    pol.reset(c1, 30, 3)
    for _ in range(45):
        o1, o2 = observe(w1), observe(w2)
        b1.update(o1)
        b2.update(o2)
        np.testing.assert_allclose(b2.target, b1.target, atol=1e-5)
        np.testing.assert_allclose(b2.found, b1.found, atol=1e-6)
        np.testing.assert_array_equal(b2.n_found, b1.n_found)
        a = pol.act(o1)
        w1.step(a)
        w2.step(a)


def _obs(cfg, level, det=None, t=0):
    k = 2 * cfg.view_radius + 1
    views = np.zeros((1, 4, k, k), np.uint8)
    if det is not None:
        views[0, 0, det[1] + k // 2, det[0] + k // 2] = 1
    return Observation(views=views, maps=np.zeros((1, 1, cfg.height, cfg.width), np.float32),
                       positions=np.array([[5, 5]]), valid=np.ones((1, 7), bool), t=np.array([t]),
                       active=np.array([True]), found_now=np.zeros(1), level=np.array([level]))


def test_a_miss_is_soft_evidence_and_the_count_is_kept():
    cfg = GridConfig(width=11, height=11, n_targets=3, levels=3, detection=TABLE)
    b = BeliefState(cfg, 1)
    b.update(_obs(cfg, 3))
    u = b.target[0]
    assert u.sum() == pytest.approx(3.0, abs=1e-4)
    out = u[0, 0]  # never in view: the prior's share, scaled up
    for ring, p in enumerate(TABLE.p_detect[2][1:], start=1):
        # a miss multiplies the odds by (1 - p) / (1 - fa) and the rescale keeps the total
        cell = u[5, 5 + ring]
        q = 3 / 121
        post = q * (1 - p) / (q * (1 - p) + (1 - q) * (1 - 0.005))
        assert 0 < cell < out
        assert cell / out == pytest.approx(post / q, rel=0.02)
    assert u[5, 5] == 0.0 or b.level[0] == 3  # the nadir cell at level 3 is a look, not a visit


def test_a_sighting_with_false_alarms_is_not_certain():
    cfg = GridConfig(width=11, height=11, n_targets=3, levels=3, detection=TABLE)
    b = BeliefState(cfg, 1)
    b.update(_obs(cfg, 3, det=(3, 0)))  # a detection at ring 3
    v = b.target[0, 5, 8]
    q = 3 / 121
    post = q * 0.45 / (q * 0.45 + (1 - q) * 0.005)
    assert 0.5 < v < 1.0 and v == pytest.approx(post, abs=0.03)
    assert b.sighted[0, 5, 8] > 0 and b.unsighted[0] == pytest.approx(3 - v, abs=1e-3)
    # level 1 does not see three cells out: nothing changes there
    b.update(_obs(cfg, 1, t=1))
    assert b.target[0, 5, 8] == pytest.approx(v, rel=0.02)
    # looked at again from level 3 and missed: the odds fall by (1 - p) / (1 - fa), then the
    # rescale (3 targets are somewhere, and all 49 cells in view missed) lifts every cell a little
    b.update(_obs(cfg, 3, t=2))
    again = v * 0.55 / (v * 0.55 + (1 - v) * 0.995)
    assert again - 1e-3 < b.target[0, 5, 8] < min(v, 1.25 * again)
