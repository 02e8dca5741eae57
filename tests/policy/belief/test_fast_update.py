"""The belief's update for exact positions (the flight's and the evaluation's case) computes only
the cells in view; the whole-array update it replaces is still the one that runs under GPS noise.
Fed the same observations, once with exact positions and once with the position as a one-hot
posterior (position_prob), the two paths must give the same belief bit for bit: the fast path
is an exact rewrite, not an approximation. Real episodes, batch 1 (the flight's block path) and
batches (the planner's index path), static and moving targets, with and without a prior."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from policy.base import observe
from policy.baselines.registry import make_policy
from policy.belief import BeliefState, model_pair, model_prior
from policy.belief.gps import cell_probabilities_xy
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

ARRAYS = ("visited", "seen", "target", "found", "age", "position", "n_found", "sighted")


def _one_hot(obs, cfg: GridConfig) -> np.ndarray:
    p = np.zeros((len(obs.positions), cfg.height, cfg.width), np.float32)
    p[np.arange(len(p)), obs.positions[:, 1], obs.positions[:, 0]] = 1.0
    return p


def _play(cfg: GridConfig, n: int, seed: int, prior: bool, gps_every: int = 0):
    """Two beliefs over one real episode batch driven by the belief planner; yields both after
    every update. gps_every > 0: every gps_every-th observation carries a blurred posterior
    (both get it), so the exact path must also hand over to and resume from the general one."""
    kw = {"prior": model_prior(cfg, samples=2000), "pair": model_pair(cfg, samples=2000)} if prior else {}
    fast, ref = BeliefState(cfg, n, **kw), BeliefState(cfg, n, **kw)
    world = BatchGridWorld(sample_episodes(cfg, n, seed), seed)
    driver = make_policy("belief", cfg)
    driver.reset(cfg, n, seed)
    rng = np.random.default_rng(seed)
    k = 0
    while not world.done.all():
        obs = observe(world)
        if gps_every and k % gps_every == gps_every - 1:
            noisy = obs.positions + rng.normal(0.0, 0.4, (n, 2))
            obs = dataclasses.replace(obs, position_prob=cell_probabilities_xy(
                noisy, 0.5, cfg.width, cfg.height).astype(np.float32))
            fast.update(obs)
            ref.update(obs)
        else:
            fast.update(obs)
            ref.update(dataclasses.replace(obs, position_prob=_one_hot(obs, cfg)))
        yield fast, ref
        world.step(driver.act(obs))
        k += 1


@pytest.mark.parametrize("n", [1, 24])
@pytest.mark.parametrize("cfg, prior", [
    (GridConfig(), False),
    (GridConfig(distribution="equidistant"), True),
    (GridConfig(motion="random_walk"), False),
    (GridConfig(motion="herd", distribution="equidistant"), False),
    (GridConfig(width=7, height=4, n_targets=3), False),
])
def test_exact_update_equals_the_general_one_bit_for_bit(cfg: GridConfig, prior: bool, n: int) -> None:
    steps = 0
    for seed in range(3 if n == 1 else 1):
        for fast, ref in _play(cfg, n, seed, prior):
            for name in ARRAYS:
                np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
            np.testing.assert_array_equal(fast.planes(), ref.planes())
            steps += 1
    assert steps >= 10


@pytest.mark.parametrize("n", [1, 8])
def test_exact_updates_after_gps_ones_still_agree(n: int) -> None:
    """Once a posterior came in, visited/seen are no longer 0/1 and the exact path must fall
    back to the whole-array formulas for them."""
    for fast, ref in _play(GridConfig(), n, 4, prior=False, gps_every=4):
        for name in ARRAYS:
            np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)


def test_planes_fill_a_given_buffer() -> None:
    cfg = GridConfig(width=5, height=4, n_targets=2)
    b = BeliefState(cfg, 2)
    world = BatchGridWorld(sample_episodes(cfg, 2, 0), 0)
    b.update(observe(world))
    out = np.full((2, 8, 4, 5), np.nan, np.float32)
    assert b.planes(out=out) is out
    np.testing.assert_array_equal(out, b.planes())
    with pytest.raises(ValueError, match="out must have shape"):
        b.planes(out=np.zeros((1, 8, 4, 5), np.float32))


def test_planes_can_leave_the_constant_planes_of_a_filled_buffer() -> None:
    cfg = GridConfig(width=5, height=4, n_targets=2)
    b = BeliefState(cfg, 1)
    world = BatchGridWorld(sample_episodes(cfg, 1, 0), 0)
    out = b.planes(out=np.zeros((1, 8, 4, 5), np.float32))
    for _ in range(4):
        world.step(np.array([0]))
        b.update(observe(world))
        np.testing.assert_array_equal(b.planes(out=out, constants=False), b.planes())
