import numpy as np
import pytest

from sim.gridworld import ConfigError, GridConfig, fixed_layout, place, sample_episodes


def _distinct(targets: np.ndarray) -> bool:
    n, r, _ = targets.shape
    flat = targets[..., 1] * 1000 + targets[..., 0]
    return all(len(np.unique(row)) == r for row in flat)


@pytest.mark.parametrize("dist", ["random", "fixed", "equidistant", "gaussian"])
def test_targets_distinct_in_map_and_off_agent(dist: str) -> None:
    cfg = GridConfig(distribution=dist)
    agent, targets = place(cfg, np.random.default_rng(3), 3000)
    assert targets.shape == (3000, 5, 2)
    assert (targets[..., 0] >= 0).all() and (targets[..., 0] < cfg.width).all()
    assert (targets[..., 1] >= 0).all() and (targets[..., 1] < cfg.height).all()
    assert _distinct(targets)
    assert not np.any(np.all(targets == agent[:, None], axis=-1))


def test_random_placement_is_uniform() -> None:
    cfg = GridConfig()
    agent, targets = place(cfg, np.random.default_rng(1), 20000)
    counts = np.bincount((targets[..., 1] * 10 + targets[..., 0]).ravel(), minlength=100)
    expected = 20000 * 5 / 100
    # chi-square with 99 dof: mean 99, sd ~14; 200 is far out in the tail
    assert ((counts - expected) ** 2 / expected).sum() < 200
    a_counts = np.bincount(agent[:, 1] * 10 + agent[:, 0], minlength=100)
    assert a_counts.min() > 100


def test_gaussian_centre_and_spread() -> None:
    cfg = GridConfig(distribution="gaussian")
    _, targets = place(cfg, np.random.default_rng(2), 5000)
    mean = targets.reshape(-1, 2).mean(axis=0)
    assert np.allclose(mean, [3, 5], atol=0.15)
    # rejection of duplicates widens the spread a little beyond sd = 1
    assert 0.9 < targets.reshape(-1, 2).std(axis=0).mean() < 1.6


def test_equidistant_nearest_neighbour_spacing_is_two() -> None:
    cfg = GridConfig(distribution="equidistant")
    _, targets = place(cfg, np.random.default_rng(4), 500)
    d = np.abs(targets[:, :, None] - targets[:, None]).sum(-1) + np.eye(5, dtype=int)[None] * 99
    assert (d.min(axis=2) == 2).all()
    shape = targets - targets.min(axis=1, keepdims=True)
    assert (shape == shape[0]).all(), "the lattice keeps one shape across episodes"
    assert len({tuple(t.min(axis=0)) for t in targets}) > 10, "its offset varies"


def test_fixed_layout_is_fixed_and_agent_varies() -> None:
    cfg = GridConfig(distribution="fixed")
    agent, targets = place(cfg, np.random.default_rng(5), 2000)
    assert (targets == fixed_layout(cfg)).all()
    assert len({tuple(a) for a in agent}) == 95


def test_sampling_is_reproducible() -> None:
    cfg = GridConfig(motion="herd", distribution="equidistant")
    a, b = sample_episodes(cfg, 50, seed=9), sample_episodes(cfg, 50, seed=9)
    assert (a.agent == b.agent).all() and (a.paths == b.paths).all()
    c = sample_episodes(cfg, 50, seed=10)
    assert not (a.paths == c.paths).all()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"width": 1},
        {"n_targets": 0},
        {"n_targets": 100},
        {"distribution": "poisson"},
        {"motion": "fly"},
        {"map_variant": "x"},
        {"t_e": 0},
        {"n_targets": 30, "distribution": "equidistant"},
    ],
)
def test_bad_config_is_a_clear_error(kwargs: dict) -> None:
    with pytest.raises(ConfigError) as e:
        GridConfig(**kwargs)
    assert str(e.value)


def test_config_round_trip() -> None:
    cfg = GridConfig(distribution="gaussian", motion="herd", map_variant="spatiotemporal")
    assert GridConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ConfigError):
        GridConfig.from_dict({"widht": 3})
