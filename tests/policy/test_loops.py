import numpy as np
import pytest

from policy.base import Observation, Policy
from policy.loops import LoopGuard, vote
from sim.gridworld import Action, BatchGridWorld, GridConfig, sample_episodes


def test_vote_prefers_the_side_with_more_unvisited_cells() -> None:
    visited = np.ones((1, 10, 10), dtype=bool)
    visited[0, 4:7, 7:10] = False  # a block of unvisited cells to the east, 2+ cells away
    a = vote(np.array([[5, 5]]), visited, np.random.default_rng(0))
    assert a[0] == Action.R


def test_vote_radius_grows_until_it_finds_unvisited_cells_and_off_map_counts_as_visited() -> None:
    visited = np.ones((1, 10, 10), dtype=bool)
    visited[0, 9, 0] = False  # far corner, radius 9 from (0, 0)... reachable only at r = 9
    a = vote(np.array([[0, 0]]), visited, np.random.default_rng(0))
    assert a[0] == Action.B  # dy = 9 > dx = 0
    none = vote(np.array([[3, 3]]), np.ones((1, 10, 10), dtype=bool), np.random.default_rng(0))
    assert none[0] == Action.N


def test_exact_diagonal_votes_both_ways_ties_at_random() -> None:
    visited = np.ones((1, 5, 5), dtype=bool)
    visited[0, 1, 1] = False  # up-left diagonal of (2, 2)
    got = {int(vote(np.array([[2, 2]]), visited, np.random.default_rng(s))[0]) for s in range(40)}
    assert got == {Action.F, Action.L}


class _Pendulum(Policy):
    """Swings right/left forever: the simplest loop."""

    name = "pendulum"

    def reset(self, cfg, n, seed, episodes=None):
        self.k = 0

    def act(self, obs: Observation) -> np.ndarray:
        self.k += 1
        return np.full(len(obs.positions), Action.R if self.k % 2 else Action.L)


def test_loop_triggers_on_the_third_visit_and_the_fallback_breaks_it() -> None:
    cfg = GridConfig(width=10, height=10, n_targets=1)
    ep = sample_episodes(cfg, 1, 0)
    ep = type(ep)(cfg, np.array([[4, 4]]), np.array([[[9, 9]]]), None, 0)
    world = BatchGridWorld(ep, 0)
    guard = LoopGuard(_Pendulum())
    guard.reset(cfg, 1, 0)
    from policy.base import observe

    seen = []
    for _ in range(6):
        seen.append(tuple(world.agent[0]))
        world.step(guard.act(observe(world)))
        if guard.loops()[0]:
            break
    # positions (4,4) (5,4) (4,4) (5,4) (4,4): the third visit of (4,4) is the trigger
    assert guard.loops()[0] == 1 and seen.count((4, 4)) == 3
    assert guard.fallback[0]
    world.run(lambda w: guard.act(observe(w)))
    assert world.success[0], "with the fallback the agent explores and finds the target"


def test_queue_is_cleared_after_landing_on_an_unvisited_cell() -> None:
    cfg = GridConfig(width=6, height=6, n_targets=1)
    ep = sample_episodes(cfg, 1, 0)
    ep = type(ep)(cfg, np.array([[2, 2]]), np.array([[[5, 5]]]), None, 0)
    world = BatchGridWorld(ep, 0)
    guard = LoopGuard(_Pendulum())
    guard.reset(cfg, 1, 0)
    from policy.base import observe

    for _ in range(5):
        world.step(guard.act(observe(world)))
    assert guard.fallback[0]
    # the fifth move was the vote's, onto an unvisited cell: the wrapped policy takes over
    guard.act(observe(world))
    assert not guard.fallback[0] and guard.qlen[0] == 1


def test_bad_parameters() -> None:
    with pytest.raises(ValueError):
        LoopGuard(_Pendulum(), alpha=1)
