"""DAgger under GPS noise: the student observes what the GPS evaluation gives (a Kalman-fused
fix: the most likely cell as its position, the posterior over cells in its belief), the teacher
labels from the true position. With the teacher driving (beta 1) the world's trajectory cannot
depend on the noise, so the labels and moves must be the exact run's, while the student's
positions, masks and belief planes are the noisy ones."""

import dataclasses

import numpy as np
import pytest

from policy.belief import PLANE_NAMES
from policy.searchnet.dagger import DaggerConfig, rollout_tasks
from policy.searchnet.rollout import collect
from sim.gridworld import GridConfig, valid_mask

GRID = GridConfig(width=6, height=6, n_targets=3)


def test_noisy_student_states_with_the_teachers_true_labels() -> None:
    (exact,) = rollout_tasks(DaggerConfig(episodes=10, chunks=1), GRID, 0, None, None)
    (noisy,) = rollout_tasks(DaggerConfig(episodes=10, chunks=1, gps_sigma=1.5), GRID, 0, None, None)
    assert noisy.gps_sigma == 1.5 and noisy.seed == exact.seed
    a, b = collect(exact), collect(noisy)
    np.testing.assert_array_equal(b["labels"], a["labels"])  # the teacher drives: same states, same labels
    np.testing.assert_array_equal(b["moves"], a["moves"])
    off = np.abs(b["positions"].astype(int) - a["positions"].astype(int)).sum(axis=1)
    assert 0.05 < (off > 0).mean() < 0.9, "sigma 1.5 m (0.75 cell) misplaces some but not most estimates"
    want = valid_mask(b["positions"].astype(np.int64), GRID.width, GRID.height, GRID.n_actions)
    np.testing.assert_array_equal(b["valid"][:, : GRID.n_actions], want)  # the student's own mask
    agent = b["planes"][:, PLANE_NAMES.index("agent")].astype(np.float32)
    np.testing.assert_allclose(agent.sum(axis=(1, 2)), 1.0, atol=1e-2)
    assert (agent.max(axis=(1, 2)) < 0.99).mean() > 0.5, "the belief holds the posterior, not a one-hot cell"
    c = collect(noisy)
    for k in b:
        np.testing.assert_array_equal(c[k], b[k], err_msg=k)  # seeded: the same data again


def test_gps_noise_is_for_static_spatial_settings_and_never_negative() -> None:
    moving = GridConfig(width=6, height=6, n_targets=3, motion="random_walk", map_variant="spatiotemporal")
    (task,) = rollout_tasks(DaggerConfig(episodes=2, chunks=1, gps_sigma=1.0), moving, 0, None, None)
    with pytest.raises(ValueError, match="static targets"):
        collect(task)
    with pytest.raises(ValueError, match="gps_sigma"):
        DaggerConfig(gps_sigma=-1.0)
    zero = dataclasses.replace(task, grid=GRID.to_dict(), gps_sigma=0.0)
    assert len(collect(zero)["labels"]) > 0
