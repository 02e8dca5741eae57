import numpy as np
import pytest

from policy.base import Observation, Policy
from policy.baselines import make_policy
from policy.evaluation import evaluate
from policy.groundtruth import optimal_lengths
from sim.gridworld import Episodes, GridConfig, sample_episodes


def test_oracle_is_optimal_on_every_setting() -> None:
    for kw in ({}, {"motion": "herd", "distribution": "equidistant", "map_variant": "spatiotemporal"}):
        cfg = GridConfig(**kw)
        r = evaluate(make_policy("oracle", cfg), cfg, 300, seed=1, batch=128, progress=False)
        assert (r.moves == r.optimal).all()
        assert r.columns["optimal_pct"] == 100.0 and r.columns["success_pct"] == 100.0


def test_same_seed_same_result_and_every_policy_meets_the_same_episodes() -> None:
    cfg = GridConfig()
    a = evaluate(make_policy("ns", cfg), cfg, 200, seed=3, batch=64, progress=False)
    b = evaluate(make_policy("ns", cfg), cfg, 200, seed=3, batch=64, progress=False)
    assert (a.moves == b.moves).all() and (a.find_moves == b.find_moves).all()
    c = evaluate(make_policy("oracle", cfg), cfg, 200, seed=3, batch=200, progress=False)
    assert (c.optimal == a.optimal).all()
    assert (a.optimal == optimal_lengths(sample_episodes(cfg, 200, 3))).all()
    d = evaluate(make_policy("ns", cfg), cfg, 200, seed=4, batch=64, progress=False)
    assert not (d.optimal == a.optimal).all(), "another seed, other episodes"


def test_collected_arrays_and_example_paths_are_consistent() -> None:
    cfg = GridConfig()
    r = evaluate(make_policy("ns", cfg), cfg, 120, seed=6, batch=50, keep_paths=5, progress=False)
    assert r.moves.shape == r.optimal.shape == (120,) and r.find_moves.shape == (120, 5)
    assert r.loops is None and (r.replaced == 0).all()
    # an episode ends at its last find (all found) or at t_e + 1
    assert (np.where(r.moves <= cfg.t_e, r.moves == r.find_moves.max(axis=1), True)).all()
    ep = sample_episodes(cfg, 5, 6)
    assert len(r.sample_paths) == 5
    for i, (path, tg) in enumerate(zip(r.sample_paths, r.sample_targets, strict=True)):
        assert len(path) == r.moves[i] + 1 and tuple(path[0]) == tuple(ep.agent[i])
        assert (np.abs(np.diff(path, axis=0)).sum(axis=1) == 1).all()
        assert {tuple(t) for t in tg} <= {tuple(p) for p in path}


def test_loop_counts_come_through_from_a_guarded_policy() -> None:
    cfg = GridConfig()
    r = evaluate(make_policy("random", cfg, loop_guard=True), cfg, 100, seed=2, batch=40, progress=False)
    assert r.loops is not None and r.loops.shape == (100,) and (r.loops > 0).all()
    assert r.columns["loop_pct"] == 100.0


def test_bad_arguments() -> None:
    cfg = GridConfig()
    with pytest.raises(ValueError, match="episodes"):
        evaluate(make_policy("ns", cfg), cfg, 0, seed=1)
    with pytest.raises(ValueError, match="batch"):
        evaluate(make_policy("ns", cfg), cfg, 10, seed=1, batch=0)


class _AlwaysFirst(Policy):
    """Always action 0: it walks into a wall and keeps choosing it."""

    name = "always_first"

    def __init__(self, off_map: str) -> None:
        self.off_map = off_map

    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        pass

    def act(self, obs: Observation) -> np.ndarray:
        return np.zeros(len(obs.positions), dtype=np.int64)


def test_the_policy_chooses_its_wall_rule() -> None:
    cfg = GridConfig(width=6, height=6, n_targets=2)
    stay = evaluate(_AlwaysFirst("stay"), cfg, 20, seed=1, progress=False)
    rand = evaluate(_AlwaysFirst("random"), cfg, 20, seed=1, progress=False)
    pinned = [p for p in stay.sample_paths if len(p) > 12]
    assert pinned and all((p[-10:] == p[-1]).all() for p in pinned), "a bump leaves the agent in place"
    assert stay.replaced.sum() > 0 and (stay.moves >= rand.moves).all()
    assert any(len(np.unique(p[-10:], axis=0)) > 1 for p in rand.sample_paths), "random valid moves wander on"
