"""DAgger rollouts fan out: on a real local ray instance they give exactly the local result."""

import numpy as np
import pytest
import torch

from policy.belief import BELIEF_CHANNELS
from policy.searchnet import SearchNet, SearchNetConfig
from policy.searchnet.dagger import DaggerConfig, gather, rollout_tasks
from sim.gridworld import GridConfig

GRID = GridConfig(width=6, height=6, n_targets=3)


def _tasks():
    torch.manual_seed(1)
    model = SearchNet(SearchNetConfig(BELIEF_CHANNELS))
    return rollout_tasks(DaggerConfig(episodes=16, chunks=2), GRID, 1, model, None)


@pytest.mark.slow
def test_ray_and_local_rollouts_give_the_same_data() -> None:
    ray = pytest.importorskip("ray")
    tasks = _tasks()
    local = gather(tasks, workers=1)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = gather(tasks, ray_address="auto")
    finally:
        ray.shutdown()
    assert local.keys() == remote.keys()
    for k in local:
        np.testing.assert_array_equal(local[k], remote[k], err_msg=k)
    assert len(local["labels"]) == int(local["moves"].sum())


def test_process_pool_and_in_process_rollouts_give_the_same_data() -> None:
    tasks = _tasks()
    a, b = gather(tasks, workers=1), gather(tasks, workers=2)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
