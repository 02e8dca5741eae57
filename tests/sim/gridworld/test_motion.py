import numpy as np
import pytest

from sim.gridworld import GridConfig, sample_episodes


@pytest.mark.parametrize("motion", ["random_walk", "herd"])
def test_targets_move_one_cell_every_third_step_and_never_collide(motion: str) -> None:
    dist = "equidistant" if motion == "herd" else "random"
    cfg = GridConfig(distribution=dist, motion=motion)
    ep = sample_episodes(cfg, 300, seed=1)
    p = ep.paths
    assert p.shape == (300, cfg.t_e + 2, 5, 2)
    step = np.abs(np.diff(p, axis=1)).sum(-1)  # (n, T, R)
    assert step.max() <= 1
    t = np.arange(step.shape[1])
    assert (step[:, t % 3 != 0] == 0).all(), "targets only move on t % 3 == 0"
    assert step[:, t % 3 == 0].mean() > 0.5, "they do move"
    assert (p >= 0).all() and (p[..., 0] < 10).all() and (p[..., 1] < 10).all()
    flat = p[..., 1] * 100 + p[..., 0]
    srt = np.sort(flat, axis=-1)
    assert (np.diff(srt, axis=-1) > 0).all(), "never two targets in one cell"


def test_herd_moves_together() -> None:
    cfg = GridConfig(distribution="equidistant", motion="herd")
    p = sample_episodes(cfg, 200, seed=2).paths
    d = np.diff(p, axis=1)[:, ::3]  # the moving transitions
    moving = np.abs(d).sum(-1) > 0
    # On moving transitions most targets share the majority direction.
    codes = (d[..., 0] + 2) * 5 + (d[..., 1] + 2)
    agree = []
    for e in range(50):
        for s in range(d.shape[1]):
            c = codes[e, s][moving[e, s]]
            if c.size >= 3:
                agree.append(np.bincount(c).max() / c.size)
    assert np.mean(agree) > 0.8


def test_static_paths_absent() -> None:
    assert sample_episodes(GridConfig(), 5, seed=0).paths is None
