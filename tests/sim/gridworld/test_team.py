"""The team grid world (issue 29): N = 1 is today's world, the separation rule, and the
PettingZoo / gymnasium front ends."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from sim.gridworld import BatchGridWorld, ConfigError, GridConfig, sample_episodes
from sim.gridworld.team import TeamGridWorld, team_starts


def test_one_agent_replays_todays_world_bit_for_bit():
    # random actions, off-map ones included: the same replacements, finds and moves
    cfg = GridConfig(motion="random_walk", map_variant="spatiotemporal")
    ep = sample_episodes(cfg, 64, 3)
    one, team = BatchGridWorld(ep, seed=5), TeamGridWorld(ep, team_starts(ep, 1), seed=5)
    rng = np.random.default_rng(0)
    while not one.done.all():
        a = rng.integers(0, cfg.n_actions, size=64)
        one.step(a)
        team.step(a[:, None])
    assert np.array_equal(one.t, team.makespan)
    assert np.array_equal(one.find_moves, team.find_moves)
    assert np.array_equal(one.trajectories(), team.trajectories()[:, :, 0])
    assert np.array_equal(one.replaced, team.replaced[:, 0])


def test_separation_no_shared_cell_no_swap():
    cfg = GridConfig(width=4, height=4, n_targets=2)
    ep = sample_episodes(cfg, 200, 1)
    w = TeamGridWorld(ep, team_starts(ep, 4), seed=2)
    rng = np.random.default_rng(1)
    for _ in range(60):
        if w.done.all():
            break
        w.step(rng.integers(0, 4, size=(200, 4)))
    traj = w.trajectories().astype(np.int64)  # (n, T, N, 2)
    same = np.all(traj[:, :, :, None] == traj[:, :, None, :], axis=-1) & ~np.eye(4, dtype=bool)
    assert not same.any()
    prev, nxt = traj[:, :-1], traj[:, 1:]
    swap = np.all(nxt[:, :, :, None] == prev[:, :, None, :], axis=-1) & \
        np.all(nxt[:, :, None, :] == prev[:, :, :, None], axis=-1) & ~np.eye(4, dtype=bool)
    assert not swap.any()
    assert w.blocked.sum() > 0  # random moves on a 4 x 4 grid do clash: the rule was exercised


def test_two_agents_heading_for_one_cell_lower_index_gets_it():
    cfg = GridConfig(width=5, height=5, n_targets=1)
    ep = sample_episodes(cfg, 1, 0)
    starts = np.array([[[1, 2], [3, 2]]])
    if (ep.targets[0] == [2, 2]).all(axis=1).any():
        pytest.skip("target on the contested cell")
    w = TeamGridWorld(ep, starts, seed=0)
    w.step(np.array([[3, 2]]))  # r and l: both into (2, 2)
    assert w.agents[0].tolist() == [[2, 2], [3, 2]] and w.blocked[0].tolist() == [0, 1]


def test_team_limits_are_clear_errors():
    ep = sample_episodes(GridConfig(), 2, 0)
    with pytest.raises(ConfigError, match="n_agents"):
        team_starts(ep, 0)


def test_pettingzoo_parallel_api_and_gymnasium_registration():
    from pettingzoo.test import parallel_api_test

    from sim.gridworld.team_env import TeamSearchParallelEnv

    parallel_api_test(TeamSearchParallelEnv(GridConfig(width=6, height=6, n_targets=2), n_agents=3), num_cycles=50)
    env = gym.make("uavsearch/GridSearch-v0", cfg=GridConfig())
    obs, _ = env.reset(seed=0)
    assert obs["view"].shape == (3, 3, 3)
    vec = gym.make_vec("uavsearch/GridSearch-v0", num_envs=8, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    rng, ends = np.random.default_rng(0), 0
    for _ in range(320):  # random moves: every sub-env ends at least once (t_e = 300) and restarts
        _, r, term, trunc, info = vec.step(rng.integers(0, 4, size=8))
        ends += int((term | trunc).sum())
    assert ends >= 8 and (info["moves"] <= 301).all()
