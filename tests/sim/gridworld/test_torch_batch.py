"""The torch grid world runs the numpy engine's episodes step for step (on CPU here; the
same code runs on a GPU when one is present)."""

import numpy as np
import pytest
import torch

from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes
from sim.gridworld.torch_batch import TorchGridWorld


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """Small tensors on a loaded 2-core machine: a second intra-op thread only spins (10x slower)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.mark.parametrize("motion,dist,variant,off_map", [
    ("static", "random", "spatial", "random"), ("static", "equidistant", "memory", "stay"),
    ("herd", "equidistant", "spatiotemporal", "random"), ("random_walk", "random", "memory", "random"),
])
def test_torch_engine_gives_identical_episodes(motion: str, dist: str, variant: str, off_map: str) -> None:
    cfg = GridConfig(width=8, height=6, motion=motion, distribution=dist, map_variant=variant)
    eps = sample_episodes(cfg, 200, 3)
    a, b = BatchGridWorld(eps, 3, off_map), TorchGridWorld(eps, 3, off_map, device="cpu")
    rng = np.random.default_rng(7)
    steps = 0
    while not a.done.all() and steps < 120:  # (moving targets run to t_e: 120 steps suffice)
        va, ma = a.observe()
        vb, mb = b.observe()
        np.testing.assert_array_equal(vb.numpy(), va)
        np.testing.assert_array_equal(mb.numpy(), ma)
        act = rng.integers(0, cfg.n_actions, a.n)
        np.testing.assert_array_equal(b.step(torch.as_tensor(act)).numpy(), a.step(act))
        steps += 1
    assert bool((b.done == torch.as_tensor(a.done)).all()) and steps > 5
    for name in ("agent", "t", "found", "find_moves", "replaced", "visited", "met", "trail", "recoveries"):
        np.testing.assert_array_equal(getattr(b, name).numpy(), getattr(a, name), err_msg=name)
    np.testing.assert_array_equal(b.trajectories().numpy(), a.trajectories())
    assert a.success.any() and a.replaced.sum() > 0, "the runs find targets and replace off-map moves"


def test_torch_engine_checks_its_actions() -> None:
    w = TorchGridWorld(sample_episodes(GridConfig(), 4, 0), 0, device="cpu")
    with pytest.raises(ValueError, match="expected 4 actions"):
        w.step(torch.zeros(3, dtype=torch.int64))
    with pytest.raises(ValueError, match="actions must be in"):
        w.step(torch.full((4,), 9))
