"""weighted_rows replaces `weights @ table` in the belief's pair correlation and the planner's
herd weighting: a BLAS product's float32 rounding changed with OpenBLAS's thread count (so the
planner's decisions depended on the machine) and its threads spun on a loaded machine. Its sums
must be the plain sequential ones, the same for a row alone as in any batch, on both its sparse
and its dense path, and agree with a float64 product to float32 rounding."""

from __future__ import annotations

import numpy as np
import pytest

from policy.belief import BeliefState, model_pair, model_prior
from policy.belief.state import weighted_rows
from sim.gridworld import GridConfig


def _sequential(w: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.zeros((len(w), t.shape[1]), np.result_type(w, t))
    for k in range(w.shape[1]):
        out += w[:, k, None] * t[k]
    return out


@pytest.mark.parametrize("n, k, m, density", [(10, 400, 400, 0.03), (24, 100, 100, 1.0), (50, 100, 100, 0.2),
                                              (7, 5, 3, 0.5), (3, 4, 4, 0.0), (1, 9, 9, 0.3)])
def test_sums_are_sequential_and_independent_of_the_batch(n: int, k: int, m: int, density: float) -> None:
    rng = np.random.default_rng(n * k)
    w = ((rng.random((n, k)) < density) * rng.random((n, k))).astype(np.float32)
    t = rng.normal(0.0, 2.0, (k, m)).astype(np.float32)
    got = weighted_rows(w, t)
    assert got.dtype == np.float32 and got.shape == (n, m)
    np.testing.assert_array_equal(got, _sequential(w, t))
    np.testing.assert_array_equal(np.concatenate([weighted_rows(w[i: i + 1], t) for i in range(n)]), got)
    np.testing.assert_allclose(got, w.astype(np.float64) @ t.astype(np.float64), rtol=0, atol=1e-4)


def test_the_belief_pool_uses_it_on_a_real_search() -> None:
    """The equidistant prior's pair correlation shapes the pool after a sighting; the pool's
    weights are the sequential sums (recomputed here from the public arrays)."""
    from policy.base import observe
    from policy.baselines.registry import make_policy
    from sim.gridworld import BatchGridWorld, sample_episodes

    cfg = GridConfig(distribution="equidistant")
    b = BeliefState(cfg, 6, model_prior(cfg, samples=2000), model_pair(cfg, samples=2000))
    world = BatchGridWorld(sample_episodes(cfg, 6, 3), 3)
    drive = make_policy("belief", cfg)
    drive.reset(cfg, 6, 3)
    for _ in range(12):
        obs = observe(world)
        b.update(obs)
        world.step(drive.act(obs))
    known = (b.sighted + b.found).reshape(6, -1)
    assert (known > 0).any(), "the search sighted something"
    np.testing.assert_array_equal(weighted_rows(known, b._pair), _sequential(known, b._pair))
