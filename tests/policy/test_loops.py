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


def _ring(x0: int, y0: int, w: int, h: int) -> list[tuple[int, int]]:
    """The perimeter cells of a w x h rectangle, clockwise from its top-left corner."""
    top = [(x0 + i, y0) for i in range(w)]
    right = [(x0 + w - 1, y0 + j) for j in range(1, h)]
    bottom = [(x0 + i, y0 + h - 1) for i in range(w - 2, -1, -1)]
    left = [(x0, y0 + j) for j in range(h - 2, 0, -1)]
    return top + right + bottom + left


class _RingWalker(Policy):
    """Walks a closed ring of cells forever: a loop of known length."""

    name = "ring"

    def __init__(self, ring: list[tuple[int, int]]) -> None:
        self.ring = ring

    def reset(self, cfg, n, seed, episodes=None):
        pass

    def act(self, obs: Observation) -> np.ndarray:
        x, y = (int(v) for v in obs.positions[0])
        nx, ny = self.ring[(self.ring.index((x, y)) + 1) % len(self.ring)]
        return np.array([{(0, -1): Action.F, (0, 1): Action.B, (-1, 0): Action.L, (1, 0): Action.R}[(nx - x, ny - y)]])


def _first_trigger(ring: list[tuple[int, int]], window: int, moves: int = 200) -> int | None:
    """Moves made when the guard first declares a loop (None if it never does)."""
    from policy.base import observe

    cfg = GridConfig(width=10, height=10, n_targets=1)
    ep = type(sample_episodes(cfg, 1, 0))(cfg, np.array([ring[0]]), np.array([[[9, 9]]]), None, 0)
    world, guard = BatchGridWorld(ep, 0), LoopGuard(_RingWalker(ring), window=window)
    guard.reset(cfg, 1, 0)
    for _ in range(moves):
        obs = observe(world)
        world.step(guard.act(obs))
        if guard.loops()[0]:
            return int(obs.t[0])
    return None


def test_a_loop_counts_only_when_the_third_visit_is_within_the_window() -> None:
    short, long_ = _ring(1, 1, 5, 6), _ring(1, 1, 6, 6)  # 18 and 20 cells
    assert len(short) == 18 and len(long_) == 20
    # 18-cycle: the start cell's third visit is position 36, 37 positions <= 40 queued
    assert _first_trigger(short, window=40) == 36
    # 20-cycle: a third visit lies 40 moves after the first, outside the last 40 positions
    assert _first_trigger(long_, window=40) is None
    assert _first_trigger(long_, window=41) == 40


def test_only_the_first_radius_with_an_unvisited_cell_votes() -> None:
    visited = np.ones((1, 10, 10), dtype=bool)
    visited[0, 5, 6] = False  # one cell right at radius 1
    visited[0, 3:8, 2:4] = False  # ten cells left at radius 2-3: never consulted
    assert vote(np.array([[5, 5]]), visited, np.random.default_rng(0))[0] == Action.R
    visited[0, 5, 6] = True  # now radius 1 is empty: the left block wins at radius 2
    assert vote(np.array([[5, 5]]), visited, np.random.default_rng(0))[0] == Action.L


def _reference_votes(pos: np.ndarray, visited: np.ndarray) -> np.ndarray:
    """The fallback's votes (f, b, l, r) for one agent, written the slow and obvious way."""
    h, w = visited.shape
    for r in range(1, max(h, w) + 1):
        votes = np.zeros(4, dtype=int)
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                x, y = pos[0] + dx, pos[1] + dy
                if not (0 <= x < w and 0 <= y < h) or visited[y, x]:
                    continue
                if abs(dy) >= abs(dx):
                    votes[0 if dy < 0 else 1] += 1
                if abs(dx) >= abs(dy):
                    votes[2 if dx < 0 else 3] += 1
        if votes.any():
            return votes
    return votes


def test_batched_vote_agrees_with_a_per_agent_reference() -> None:
    rng = np.random.default_rng(7)
    n = 300
    visited = rng.random((n, 8, 9)) < rng.uniform(0.5, 1.0, size=(n, 1, 1))
    pos = np.stack([rng.integers(0, 9, n), rng.integers(0, 8, n)], axis=1)
    visited[np.arange(n), pos[:, 1], pos[:, 0]] = True
    got = vote(pos, visited, np.random.default_rng(1))
    for i in range(n):
        ref = _reference_votes(pos[i], visited[i])
        if not ref.any():
            assert got[i] == Action.N
        else:
            assert ref[got[i]] == ref.max(), f"agent {i}: chose {got[i]} with votes {ref}"


def test_every_trigger_counts_one_loop_and_the_guard_sees_what_m_shows() -> None:
    from policy.base import observe

    cfg = GridConfig(n_targets=1)
    ep = type(sample_episodes(cfg, 1, 0))(cfg, np.array([[0, 0]]), np.array([[[9, 9]]]), None, 0)
    world, guard = BatchGridWorld(ep, 0), LoopGuard(_Pendulum())
    guard.reset(cfg, 1, 0)
    entries = 0
    while not world.done.all():
        before = bool(guard.fallback[0])
        obs = observe(world)
        world.step(guard.act(obs))
        entries += int(guard.fallback[0] and not before)
        # the guard's own visited mask is M's visited cells (> 0) before this move
        assert (guard.visited[0] == (obs.maps[0, 0] > 0)).all()
    assert guard.loops()[0] == entries >= 10  # the pendulum loops again after every break


@pytest.mark.parametrize("inner, window", [("random", 40), ("random", 5), ("pendulum", 40), ("pendulum", 5)])
def test_single_episode_path_equals_the_array_path(inner: str, window: int) -> None:
    """A single episode (the flight) goes through LoopGuard._act_one: the same actions, loop
    counts and queue as the array path, on real episodes, with the ring overflowing (small
    windows) and with fallbacks entered and left many times."""
    from policy.base import observe
    from policy.baselines.registry import make_policy

    cfg = GridConfig(width=7, height=6, n_targets=3)
    triggers = 0
    for seed in range(8):
        guards = []
        for scalar in (True, False):
            g = LoopGuard(make_policy("random", cfg) if inner == "random" else _Pendulum(), window=window)
            g.scalar_one = scalar
            g.reset(cfg, 1, seed)
            guards.append(g)
        world = BatchGridWorld(sample_episodes(cfg, 1, seed), seed)
        while not world.done.all():
            obs = observe(world)
            a, b = (g.act(obs) for g in guards)
            assert np.array_equal(a, b), (seed, int(obs.t[0]))
            fast, ref = guards
            for name in ("count", "fallback", "qlen", "visited"):
                assert np.array_equal(getattr(fast, name), getattr(ref, name)), name
            k = min(int(ref.qlen[0]), window)
            assert np.array_equal(fast.queue[0, :k], ref.queue[0, :k])
            world.step(a)
        triggers += int(ref.count[0])
    assert triggers >= 8
