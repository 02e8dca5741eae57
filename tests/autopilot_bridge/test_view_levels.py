"""The companion's view at an altitude level is the grid world's: blobs of every target in the
frame, read at the level's camera height with the camera off its cell's centre, give the
(4, W, W) window BatchGridWorld shows a policy (perfect detection), at levels 2 and 3, at every
level flown, in the field's middle and at its corners."""

import numpy as np
import pytest

from autopilot_bridge.detector import CAMERA_BELOW_M, Blob, px_per_m
from autopilot_bridge.view import blobs_to_view, level_valid_moves, level_view
from sim.gridworld import (
    Action,
    BatchGridWorld,
    DetectionTable,
    Episodes,
    GridConfig,
    level_height_m,
)


def _blobs(targets: np.ndarray, camera_ne: np.ndarray, height_m: float) -> list[Blob]:
    """A whole blob per target (x, y) whose offset from the camera reads back its cell's centre."""
    k = px_per_m(height_m, 50)
    out = []
    for x, y in targets:
        dn, de = -2.0 * y - camera_ne[0], 2.0 * x - camera_ne[1]
        out.append(Blob(row=-dn * k, col=de * k, pixels=100, cut=(False, False, False, False)))
    return out


@pytest.mark.parametrize("levels", [2, 3])
def test_the_level_window_is_the_grid_worlds(levels: int) -> None:
    cfg = GridConfig(width=12, height=9, n_targets=14, levels=levels, detection=DetectionTable.perfect(levels))
    rng = np.random.default_rng(levels)
    cells = rng.choice(cfg.width * cfg.height, size=cfg.n_targets + 3, replace=False)
    xy = np.stack([cells % cfg.width, cells // cfg.width], axis=1)
    for agent in ([6, 4], [0, 0], [11, 8], [1, 7]):
        targets = np.array([c for c in xy if tuple(c) != tuple(agent)][: cfg.n_targets])
        ep = Episodes(cfg, np.array([agent]), targets[None], None, seed=0)
        world = BatchGridWorld(ep, 0)
        for level in range(1, levels + 1):
            if level > 1:
                world.step(np.array([Action.CLIMB]))
            assert world.level[0] == level
            expected = world.observe()[0][0]
            cell = np.array(agent)
            height = level_height_m(level) - CAMERA_BELOW_M
            camera = np.array([-2.0 * agent[1] + 0.3, 2.0 * agent[0] - 0.4])  # off its cell's centre
            view = blobs_to_view(_blobs(targets, camera, height), camera, height, cell, cfg.width, cfg.height,
                                 radius=level)
            got = level_view(view, level, levels, cell, cfg.width, cfg.height)
            assert got.shape == expected.shape == (4, 2 * levels + 1, 2 * levels + 1)
            np.testing.assert_array_equal(got, expected, err_msg=f"agent {agent}, level {level}")
            np.testing.assert_array_equal(level_valid_moves(cell, level, cfg), world.valid_actions()[0])


def test_radius_one_is_the_papers_view() -> None:
    """blobs_to_view's default is the 3 x 3 view, bit for bit the radius-1 window."""
    camera, cell = np.array([-4.2, 6.1]), np.array([3, 2])
    blobs = _blobs(np.array([[4, 2], [3, 3], [5, 2]]), camera, 3.44)
    a = blobs_to_view(blobs, camera, 3.44, cell, 10, 10)
    b = blobs_to_view(blobs, camera, 3.44, cell, 10, 10, radius=1)
    assert a.shape == (3, 3, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert a[0].sum() == 2 and a[0, 1, 2] == 1 and a[0, 2, 1] == 1  # (5, 2) is two cells out
