import numpy as np
import pytest

from policy.base import observe
from policy.baselines import known_policies, make_policy, serpentine
from sim.gridworld import Action, BatchGridWorld, GridConfig, sample_episodes


def _run(name: str, cfg: GridConfig, n: int, seed: int) -> BatchGridWorld:
    ep = sample_episodes(cfg, n, seed)
    p = make_policy(name, cfg)
    p.reset(cfg, n, seed, ep if p.needs_truth else None)
    w = BatchGridWorld(ep, seed)
    w.run(lambda w: p.act(observe(w)))
    return w


def test_ns_steps_onto_a_visible_unvisited_target() -> None:
    cfg = GridConfig(width=5, height=5, n_targets=1)
    ep = sample_episodes(cfg, 1, 0)
    ep = type(ep)(cfg, np.array([[2, 2]]), np.array([[[3, 1]]]), None, 0)
    p = make_policy("ns", cfg)
    p.reset(cfg, 1, 0)
    w = BatchGridWorld(ep, 0)
    first = p.act(observe(w))[0]
    assert first in (Action.R, Action.F)
    w.step(np.array([first]))
    w.step(p.act(observe(w)))
    assert w.success[0] and w.t[0] == 2


def test_serpentine_covers_every_cell_once() -> None:
    for corner in range(4):
        route = serpentine(7, 5, corner)
        assert len({tuple(c) for c in route}) == 35
        assert (np.abs(np.diff(route, axis=0)).sum(axis=1) == 1).all()


@pytest.mark.parametrize("name", ["ns", "frontier", "lawnmower"])
def test_explorers_find_everything_in_time(name: str) -> None:
    w = _run(name, GridConfig(), 300, 1)
    assert w.success.all() and (w.t <= 150).all()


def test_ns_matches_the_papers_row_roughly() -> None:
    w = _run("ns", GridConfig(), 1500, 2)
    # paper: 8.13 % over 100 moves, 0.34 % optimal; NS is a fixed algorithm, so close
    assert 4.0 < 100 * (w.t > 100).mean() < 12.0


def test_random_policy_uses_valid_moves_only() -> None:
    w = _run("random", GridConfig(motion="random_walk", map_variant="spatiotemporal"), 50, 3)
    assert (w.replaced == 0).all()


def test_registry_names_and_errors() -> None:
    assert {"oracle", "cu", "ns", "frontier", "lawnmower", "random"} <= set(known_policies())
    with pytest.raises(KeyError, match="unknown policy"):
        make_policy("nope")


def test_runs_are_reproducible() -> None:
    a, b = _run("ns", GridConfig(), 100, 4), _run("ns", GridConfig(), 100, 4)
    assert (a.t == b.t).all()
