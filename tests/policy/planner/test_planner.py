"""The belief planner: its tour is optimal once every target is sighted, it works from
observations only, and it beats the simple explorers on the same episodes."""

from __future__ import annotations

import numpy as np
import pytest

from policy.base import observe
from policy.baselines import make_policy
from policy.evaluation.runner import evaluate
from policy.groundtruth import pt_bruteforce
from policy.planner import BeliefPlanner, PlannerParams
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


@pytest.mark.parametrize("dist", ["random", "equidistant"])
def test_tour_is_optimal_once_every_target_is_sighted(dist):
    cfg = GridConfig(distribution=dist, width=8, height=8, n_targets=5)
    n, seed = 150, 21
    ep = sample_episodes(cfg, n, seed)
    world = BatchGridWorld(ep, seed)
    pol = BeliefPlanner(prior="model" if dist == "equidistant" else None)
    pol.reset(cfg, n, seed)
    entry_t = np.full(n, -1)
    entry_pos = np.zeros((n, 2), np.int64)
    left: dict[int, np.ndarray] = {}
    while not world.done.all():
        obs = observe(world)
        before = pol.in_tour.copy()
        a = pol.act(obs)
        for i in np.flatnonzero(pol.in_tour & ~before):
            entry_t[i], entry_pos[i] = world.t[i], world.agent[i]
            todo = ep.targets[i][~world.found[i]]
            left[i] = todo
            # the planner's sighted set is exactly the truth's unfound targets
            planned = {tuple(c) for c in pol.tour[i, : pol.tour_len[i]]}
            assert planned == {tuple(c) for c in todo}
        world.step(a)
    assert world.success.all()
    toured = np.flatnonzero(entry_t >= 0)
    assert len(toured) > n // 2  # most episodes sight every target before finishing
    for i in toured:
        if len(left[i]) == 0:
            continue
        best = pt_bruteforce(entry_pos[i][None], left[i][None])[0]
        assert world.t[i] - entry_t[i] == best, f"episode {i}: tour {world.t[i] - entry_t[i]} vs optimal {best}"


def test_planner_reads_no_truth_and_beats_the_simple_explorers():
    cfg = GridConfig()
    res = {name: evaluate(make_policy(name, cfg), cfg, 300, 99, progress=False) for name in ("belief", "frontier", "ns")}
    assert not make_policy("belief", cfg).needs_truth
    assert (res["belief"].moves <= cfg.t_e).all()
    assert res["belief"].moves.mean() < 0.9 * res["frontier"].moves.mean()
    assert res["belief"].moves.mean() < 0.75 * res["ns"].moves.mean()


def test_prior_helps_on_gaussian_and_moving_targets_are_all_found():
    g = GridConfig(distribution="gaussian")
    plain = evaluate(BeliefPlanner(), g, 200, 5, progress=False).moves.mean()
    told = evaluate(BeliefPlanner(prior="model"), g, 200, 5, progress=False).moves.mean()
    assert told < 0.8 * plain
    for motion, dist in (("random_walk", "random"), ("herd", "equidistant")):
        cfg = GridConfig(distribution=dist, motion=motion, map_variant="spatiotemporal")
        r = evaluate(make_policy("belief", cfg), cfg, 100, 5, progress=False)
        assert r.columns["success_pct"] >= 95.0


def test_bad_prior_and_params_are_clear_errors():
    with pytest.raises(ValueError, match="prior must be"):
        BeliefPlanner(prior=3).reset(GridConfig(), 2, 0)
    with pytest.raises(ValueError, match="pickup"):
        PlannerParams(pickup=-1)
    with pytest.raises(FileNotFoundError):
        BeliefPlanner(prior="/nonexistent/dataset").reset(GridConfig(), 2, 0)


@pytest.mark.parametrize("radius", [1, 2])
@pytest.mark.parametrize("shape", [(3, 6, 7), (1, 2, 2), (4, 20, 20)])
def test_window_sums_equal_the_shifted_copies_bit_for_bit(radius: int, shape: tuple[int, int, int]) -> None:
    """_window reads the shifted copies as slices of one padded array; the sums (and so the
    planner's decisions) must be the ones of adding belief.state._shift copies in order."""
    from policy.belief.state import _shift
    from policy.planner.planner import _window

    rng = np.random.default_rng(radius)
    work: dict = {}  # the planner's buffers, reused from call to call
    for dtype in (np.float64, np.float32, np.float64):
        a = (rng.random(shape) - 0.3).astype(dtype) * 10.0 ** rng.integers(-6, 3, shape)
        want = np.zeros_like(a)
        for dy in range(-radius, radius + 1):
            for dx in range(-radius, radius + 1):
                want += _shift(a, dy, dx)
        for got in (_window(a, radius), _window(a, radius, work)):
            assert got.dtype == a.dtype and got.shape == a.shape
            np.testing.assert_array_equal(got, want)
