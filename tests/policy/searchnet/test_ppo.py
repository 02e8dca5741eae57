import numpy as np
import torch

from policy.belief import BELIEF_CHANNELS
from policy.searchnet import SearchNet, SearchNetConfig
from policy.searchnet.ppo import PpoConfig, run_ppo, truth_plane
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


def test_a_short_ppo_run_improves_the_return() -> None:
    torch.manual_seed(0)
    grid = GridConfig(width=5, height=5, n_targets=2, t_e=60)
    actor = SearchNet(SearchNetConfig(BELIEF_CHANNELS))
    critic = SearchNet(SearchNetConfig(BELIEF_CHANNELS, privileged_channels=1))
    pc = PpoConfig(updates=7, episodes=64, lr=1e-3, minibatch=256, step_cost=0.05)
    hist = run_ppo(actor, critic, grid, pc)
    first, last = hist[0], hist[-2:]
    assert np.mean([h["return"] for h in last]) > first["return"] + 0.5
    assert np.mean([h["moves"] for h in last]) < first["moves"]


def test_the_critics_truth_plane_holds_exactly_the_unfound_targets() -> None:
    grid = GridConfig(width=6, height=6, n_targets=3)
    ep = sample_episodes(grid, 5, 1)
    world = BatchGridWorld(ep, 1)
    rng = np.random.default_rng(0)
    for _ in range(40):
        world.step(rng.integers(0, 4, 5))
        plane = truth_plane(world)[:, 0]
        for k in range(5):
            want = np.zeros((6, 6), bool)
            for (x, y), f in zip(world.targets()[k], world.found[k], strict=True):
                if not f:
                    want[y, x] = True
            np.testing.assert_array_equal(plane[k] > 0, want)
