import numpy as np
import pytest

from policy.groundtruth import (
    held_karp,
    intercept,
    intercept_scan,
    lookahead_bruteforce,
    lookahead_dp,
    optimal_lengths,
    pt_bruteforce,
    solve,
    step_towards,
)
from sim.gridworld import Action, BatchGridWorld, Episodes, GridConfig, sample_episodes


@pytest.mark.parametrize("r", [1, 2, 5, 7, 8])
def test_held_karp_equals_brute_force(r: int) -> None:
    ep = sample_episodes(GridConfig(n_targets=r), {7: 40, 8: 8}.get(r, 150), seed=r)
    hk, orders = held_karp(ep.agent, ep.targets, np.random.default_rng(0))
    assert (hk == pt_bruteforce(ep.agent, ep.targets)).all()
    assert (np.sort(orders, axis=1) == np.arange(r)).all(), "orders are permutations"


def test_optimal_length_statistics_match_the_reference() -> None:
    # authors-code-facts: mean 20.9 (sd 3.96, median 21, range 7-36) over 20k episodes
    lengths = optimal_lengths(sample_episodes(GridConfig(), 4000, seed=11))
    assert abs(lengths.mean() - 20.93) < 0.3
    assert abs(lengths.std() - 3.96) < 0.25
    assert np.median(lengths) == 21


@pytest.mark.parametrize("motion,dist", [("random_walk", "random"), ("herd", "equidistant")])
def test_lookahead_dp_equals_exhaustive_orders(motion: str, dist: str) -> None:
    ep = sample_episodes(GridConfig(motion=motion, distribution=dist), 120, seed=3)
    dp, _ = lookahead_dp(ep.agent, ep.paths, np.random.default_rng(1))
    assert (dp == lookahead_bruteforce(ep.agent, ep.paths)).all()


def test_interception_jumps_equal_a_scan_of_the_whole_horizon() -> None:
    # a large grid: interceptions far beyond any fixed search window
    ep = sample_episodes(GridConfig(width=45, height=45, n_targets=4, motion="random_walk"), 300, 4)
    rng = np.random.default_rng(0)
    n = len(ep)
    k = rng.integers(0, 4, n)
    cell = rng.integers(0, 45, (n, 2))
    time = rng.integers(0, 280, n)
    t, c = intercept(ep.paths, k, cell, time)
    ts, cs = intercept_scan(ep.paths, k, cell, time)
    assert (t == ts).all() and (c == cs).all()
    assert (t >= time).all() and (t - time).max() > 64


def test_lookahead_dp_on_a_large_grid_and_six_targets() -> None:
    ep = sample_episodes(GridConfig(width=40, height=40, n_targets=3, motion="random_walk"), 60, 2)
    assert (lookahead_dp(ep.agent, ep.paths)[0] == lookahead_bruteforce(ep.agent, ep.paths)).all()
    ep = sample_episodes(GridConfig(n_targets=6, motion="herd"), 12, 6)
    assert (lookahead_dp(ep.agent, ep.paths)[0] == lookahead_bruteforce(ep.agent, ep.paths)).all()


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"distribution": "gaussian"},
        {"motion": "random_walk"},
        {"motion": "herd", "distribution": "equidistant"},
        {"motion": "random_walk", "width": 40, "height": 40, "n_targets": 3},
    ],
)
def test_replayed_plans_find_all_targets_in_the_optimal_number_of_moves(kwargs: dict) -> None:
    ep = sample_episodes(GridConfig(**kwargs), 400, seed=5)
    plans = solve(ep, "pt", seed=2)
    assert (plans.lengths == optimal_lengths(ep)).all()
    assert ((plans.actions >= 0).sum(axis=1) == plans.lengths).all()
    world = replay(ep, plans.actions)
    assert world.found.all() and (world.t == plans.lengths).all() and world.replaced.sum() == 0


def replay(ep: Episodes, actions: np.ndarray) -> BatchGridWorld:
    """Play recorded actions in a fresh world, as the evaluation would see them."""
    world = BatchGridWorld(ep, seed=99)
    for col in actions.T:
        world.step(np.where(col < 0, 0, col))
    return world


def test_cu_walks_to_a_nearest_unvisited_target_each_leg() -> None:
    ep = sample_episodes(GridConfig(n_targets=6), 300, seed=12)
    plans = solve(ep, "cu", seed=3)
    world = replay(ep, plans.actions)
    assert world.found.all() and (world.t == plans.lengths).all()
    for i in range(len(ep)):
        order = np.argsort(world.find_moves[i])
        pos, t, left = ep.agent[i], 0, set(range(6))
        for k in order:
            d = {j: int(np.abs(ep.targets[i, j] - pos).sum()) for j in left}
            assert d[k] == min(d.values()), f"episode {i}: target {k} is not a nearest one"
            assert world.find_moves[i, k] - t == d[k], "each leg is a shortest path"
            pos, t = ep.targets[i, k], world.find_moves[i, k]
            left.remove(k)


def test_cu_is_never_better_than_pt_and_often_optimal() -> None:
    ep = sample_episodes(GridConfig(), 2000, seed=7)
    cu = solve(ep, "cu", seed=1).lengths
    pt = optimal_lengths(ep)
    assert (cu >= pt).all()
    assert 0.5 < (cu == pt).mean() < 0.8  # the paper: CU optimal in ~60 % of instances


def test_step_towards_follows_eq3_sectors() -> None:
    rng = np.random.default_rng(0)
    pos = np.zeros((6, 2), dtype=np.int64)
    goal = np.array([[3, 1], [-3, 1], [1, 3], [1, -3], [0, 0], [2, 2]])
    a = step_towards(pos, goal, rng)
    assert list(a[:5]) == [Action.R, Action.L, Action.B, Action.F, Action.N]
    diag = {int(step_towards(pos[:1], goal[5:], np.random.default_rng(s))[0]) for s in range(30)}
    assert diag == {Action.R, Action.B}, "exact diagonal: either way at random"


def test_solver_is_reproducible_and_ties_vary_with_seed() -> None:
    ep = sample_episodes(GridConfig(), 300, seed=9)
    a, b = solve(ep, "pt", seed=4), solve(ep, "pt", seed=4)
    assert (a.actions == b.actions).all()
    c = solve(ep, "pt", seed=5)
    assert (c.lengths == a.lengths).all() and not (c.actions == a.actions).all()


def test_batched_in_chunks_gives_the_same_optimum(monkeypatch: pytest.MonkeyPatch) -> None:
    import policy.groundtruth.pt as pt

    ep = sample_episodes(GridConfig(n_targets=5), 300, seed=21)
    whole = held_karp(ep.agent, ep.targets)[0]
    mv = sample_episodes(GridConfig(n_targets=4, motion="herd"), 100, seed=21)
    whole_mv = lookahead_dp(mv.agent, mv.paths)[0]
    monkeypatch.setattr(pt, "TABLE_ENTRIES", 700)  # a few episodes per chunk
    assert (held_karp(ep.agent, ep.targets)[0] == whole).all()
    assert (whole == pt_bruteforce(ep.agent, ep.targets)).all()
    assert (lookahead_dp(mv.agent, mv.paths)[0] == whole_mv).all()
