import numpy as np
import pytest
import torch

from policy.base import observe
from policy.baselines.registry import make_policy
from policy.belief import BELIEF_CHANNELS
from policy.loops import LoopGuard
from policy.searchnet import SearchNet, SearchNetConfig, SearchNetPolicy, save_searchnet
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


@pytest.fixture
def checkpoint(tmp_path):
    torch.manual_seed(0)
    return save_searchnet(tmp_path / "sn.pt", SearchNet(SearchNetConfig(BELIEF_CHANNELS)), seed=0)


def test_static_targets_get_the_papers_loop_guard_moving_ones_do_not(checkpoint) -> None:
    assert isinstance(make_policy("searchnet", GridConfig(), checkpoint=checkpoint), LoopGuard)
    moving = make_policy("searchnet", GridConfig(motion="herd", distribution="equidistant"), checkpoint=checkpoint)
    assert isinstance(moving, SearchNetPolicy)
    assert isinstance(make_policy("searchnet", GridConfig(), checkpoint=checkpoint, loop_guard=False),
                      SearchNetPolicy)


def _actions(policy: SearchNetPolicy, seed: int) -> np.ndarray:
    cfg = GridConfig(width=6, height=6, n_targets=3)
    ep = sample_episodes(cfg, 16, 5)
    policy.reset(cfg, 16, seed)
    world = BatchGridWorld(ep, 5)
    out = []
    for _ in range(10):
        a = policy.act(observe(world))
        out.append(a)
        world.step(a)
    return np.stack(out)


def test_sampling_is_seeded_and_greedy_is_the_argmax(checkpoint) -> None:
    hot = make_policy("searchnet", checkpoint=checkpoint, loop_guard=False, temperature=1.0)
    assert np.array_equal(_actions(hot, 1), _actions(hot, 1))
    greedy = make_policy("searchnet", checkpoint=checkpoint, loop_guard=False)
    assert not np.array_equal(_actions(hot, 1), _actions(greedy, 1))
    with pytest.raises(ValueError, match="temperature"):
        SearchNetPolicy(SearchNet(SearchNetConfig(BELIEF_CHANNELS)), temperature=-1.0)
