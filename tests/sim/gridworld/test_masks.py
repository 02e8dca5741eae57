"""Masked fields in the grid world: BFS distances, random field classes, and episodes on a mask
(nothing ever stands on a masked cell; the view and the moves treat it as off the map)."""

from collections import deque

import numpy as np
import pytest

from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes
from sim.gridworld.mask_fields import MASK_CLASSES, random_mask, random_masks
from sim.gridworld.masks import UNREACHABLE, distance_fields, largest_component
from sim.gridworld.observations import VISITED_VALUE


def _bfs(mask: np.ndarray, sx: int, sy: int) -> np.ndarray:
    h, w = mask.shape
    d = np.full((h, w), UNREACHABLE, np.int64)
    d[sy, sx] = 0
    q = deque([(sx, sy)])
    while q:
        x, y = q.popleft()
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            nx, ny = x + dx, y + dy
            if 0 <= nx < w and 0 <= ny < h and mask[ny, nx] and d[ny, nx] == UNREACHABLE:
                d[ny, nx] = d[y, x] + 1
                q.append((nx, ny))
    return d


def test_distance_fields_are_bfs_around_holes() -> None:
    rng = np.random.default_rng(3)
    mask = rng.random((6, 9, 11)) < 0.7
    src = np.stack([rng.integers(0, 11, 6), rng.integers(0, 9, 6)], axis=1)
    mask[np.arange(6), src[:, 1], src[:, 0]] = True
    got = distance_fields(mask, src)
    for i in range(6):
        assert np.array_equal(got[i], _bfs(mask[i], *src[i]))
    both = distance_fields(mask, np.stack([src, src[::-1]], axis=1))  # k sources per episode
    assert both.shape == (6, 2, 9, 11) and np.array_equal(both[:, 0], got)


def test_largest_component() -> None:
    m = np.zeros((4, 7), bool)
    m[:, :2] = True  # 8 cells
    m[1:3, 4:] = True  # 6 cells
    assert np.array_equal(largest_component(m), np.pad(np.ones((4, 2), bool), ((0, 0), (0, 5))))


@pytest.mark.parametrize("kind", MASK_CLASSES)
def test_random_fields_have_the_area_are_connected_and_seeded(kind: str) -> None:
    for seed in range(4):
        m = random_mask(kind, 60, seed)
        assert m.sum() == 60 and m[0].any() and m[-1].any() and m[:, 0].any() and m[:, -1].any()
        assert np.array_equal(largest_component(m), m)  # 4-connected
        assert np.array_equal(m, random_mask(kind, 60, seed))
    batch = random_masks(kind, 60, 5, 1)
    assert batch.shape[0] == 5 and (batch.reshape(5, -1).sum(axis=1) == 60).all()
    if kind == "holes":  # a hole: a masked cell of the box that no path from outside the box reaches
        enclosed = 0
        for f in (random_mask(kind, 60, s) for s in range(6)):
            outside = ~np.pad(f, 1)
            enclosed += int((distance_fields(outside[None], np.array([[0, 0]]))[0] >= UNREACHABLE).sum() - f.sum())
        assert enclosed > 0


@pytest.mark.parametrize("setting", [
    {}, {"distribution": "gaussian", "gaussian_mean": (5.0, 5.0), "gaussian_sd": 2.0},
    {"distribution": "equidistant"}, {"motion": "random_walk", "map_variant": "spatiotemporal"},
    {"motion": "herd", "distribution": "equidistant", "map_variant": "spatiotemporal"},
    {"map_variant": "memory"},
])
def test_episodes_on_a_mask_never_touch_masked_cells(setting: dict) -> None:
    masks = random_masks("holes", 70, 40, 2)
    h, w = masks.shape[1:]
    cfg = GridConfig(width=w, height=h, t_e=60, **setting)
    ep = sample_episodes(cfg, 40, 5, masks)
    assert ep.mask.shape == (40, h, w) and not ep.mask.flags.writeable
    rows = np.arange(40)
    world = BatchGridWorld(ep, 5)
    rng = np.random.default_rng(0)
    while not world.done.all():
        tg = world.targets()
        assert masks[rows[:, None], tg[..., 1], tg[..., 0]].all()  # targets only on searchable cells
        assert masks[rows, world.agent[:, 1], world.agent[:, 0]].all()
        v, m = world.observe()
        valid = world.valid_actions()
        for a in range(4):  # a move is valid iff it lands on a searchable cell, like the map's edge
            from sim.gridworld import DELTAS

            nx, ny = world.agent[:, 0] + DELTAS[a, 0], world.agent[:, 1] + DELTAS[a, 1]
            on = (nx >= 0) & (nx < w) & (ny >= 0) & (ny < h)
            on &= masks[rows, np.clip(ny, 0, h - 1), np.clip(nx, 0, w - 1)]
            assert np.array_equal(valid[:, a], on)
            # the view's off-map channel shows exactly the blocked slots
            assert np.array_equal(v[:, 1, 1 + DELTAS[a, 1], 1 + DELTAS[a, 0]].astype(bool), ~on)
        if cfg.map_variant != "spatiotemporal":  # M: masked cells read as visited
            assert (m[:, 0][~masks] == VISITED_VALUE).all()
        world.step(rng.integers(0, cfg.n_actions, 40))
    if cfg.moving:
        assert masks[rows[:, None, None], ep.paths[..., 1], ep.paths[..., 0]].all()


def test_no_mask_is_todays_episodes() -> None:
    cfg = GridConfig(motion="herd", distribution="equidistant", map_variant="spatiotemporal")
    a, b = sample_episodes(cfg, 30, 9), sample_episodes(cfg, 30, 9, None)
    assert b.mask is None and np.array_equal(a.paths, b.paths) and np.array_equal(a.agent, b.agent)


def test_bad_masks_are_refused() -> None:
    cfg = GridConfig()
    with pytest.raises(ValueError, match="shape"):
        sample_episodes(cfg, 3, 0, np.ones((9, 10), bool))
    with pytest.raises(ValueError, match="bool"):
        sample_episodes(cfg, 3, 0, np.ones((10, 10)))
    small = np.zeros((10, 10), bool)
    small[0, :4] = True
    with pytest.raises(ValueError, match="searchable cells"):
        sample_episodes(cfg, 3, 0, small)
