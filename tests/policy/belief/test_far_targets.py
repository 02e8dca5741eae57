"""Targets sighted beyond the 3 x 3 view (Observation.far_targets, BeliefState._fold_far): a real
camera's frame edge shows the near end of a target one or two cells out. Each sighting is a
likelihood over cells, placed by Bayes over where targets can be; the planner then goes for it
instead of passing it by (flight seeds 25 and 103)."""

from __future__ import annotations

import numpy as np
import pytest

from policy.base import Observation
from policy.belief import BeliefState
from policy.planner import BeliefPlanner
from sim.gridworld import DELTAS, GridConfig

CFG = GridConfig(width=7, height=7, n_targets=3)


def _empty_view(x: int, y: int) -> np.ndarray:
    v = np.zeros((3, 3, 3), np.uint8)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if not (0 <= x + dx < CFG.width and 0 <= y + dy < CFG.height):
                v[1, dy + 1, dx + 1] = 1
    v[2, 1, 1] = 1
    return v


def _obs(x: int, y: int, t: int, far: dict[tuple[int, int], float] | None = None) -> Observation:
    f = None
    if far is not None:
        f = np.zeros((1, 1, CFG.height, CFG.width), np.float32)
        for (cx, cy), w in far.items():
            f[0, 0, cy, cx] = w
    return Observation(views=_empty_view(x, y)[None], maps=None, positions=np.array([[x, y]]),
                       valid=np.ones((1, 4), bool), t=np.array([t]), active=np.array([True]), far_targets=f)


def test_a_far_sighting_lands_where_a_target_can_be() -> None:
    b = BeliefState(CFG, 1)
    b.update(_obs(3, 3, 0))
    # one cell east (4, 3) was just seen empty, two cells east (5, 3) was not: the near end at
    # the frame's east edge is the target two cells out, whatever the likelihood's 30/70 says
    b.update(_obs(3, 3, 1, {(4, 3): 0.7, (5, 3): 0.3}))
    assert b.sighted[0, 3, 5] > 0.8
    assert b.sighted[0, 3, 4] < 0.2
    assert abs(float(b.sighted.sum()) - 1.0) < 0.05, "one target, not two"
    # seen again from the same place: no second target, and the view showing (4, 3) empty
    # again moves the rest of the mass to (5, 3)
    first = float(b.sighted[0, 3, 5])
    b.update(_obs(3, 3, 2, {(4, 3): 0.7, (5, 3): 0.3}))
    assert abs(float(b.sighted.sum()) - 1.0) < 0.05
    assert b.sighted[0, 3, 5] > first
    # the unseen pool lost the sighted target: 3 targets = 1 sighted + 2 in the pool
    assert abs(float(b.target.sum()) - 3.0) < 1e-3
    # both candidates unseen: the likelihood decides
    b2 = BeliefState(CFG, 1)
    b2.update(_obs(1, 1, 0, {(4, 3): 0.7, (5, 3): 0.3}))
    np.testing.assert_allclose([b2.sighted[0, 3, 4], b2.sighted[0, 3, 5]], [0.7, 0.3], atol=1e-5)


def test_a_far_sighting_on_a_found_targets_cell_is_that_target() -> None:
    b = BeliefState(CFG, 1)
    v = _empty_view(3, 3)
    v[0, 1, 1] = 1  # a target under the agent: found
    b.update(Observation(views=v[None], maps=None, positions=np.array([[3, 3]]), valid=np.ones((1, 4), bool),
                         t=np.array([0]), active=np.array([True])))
    assert b.n_found[0] == pytest.approx(1.0)
    b.update(_obs(1, 3, 2))
    # sighted from (1, 3) where only the found target's cell could be: nothing new
    b.update(_obs(1, 3, 3, {(3, 3): 1.0}))
    assert float(b.sighted.sum()) < 1e-3


def test_bad_far_targets_are_refused() -> None:
    b = BeliefState(CFG, 1)
    with pytest.raises(ValueError, match="far_targets"):
        b.update(Observation(views=_empty_view(3, 3)[None], maps=None, positions=np.array([[3, 3]]),
                             valid=np.ones((1, 4), bool), t=np.array([0]), active=np.array([True]),
                             far_targets=np.zeros((1, 1, 3, 3), np.float32)))


def test_the_planner_goes_for_a_target_sighted_beyond_the_view() -> None:
    """Come up column 3 from the south edge: at (3, 3) the planner goes on north; told of a
    target two cells east (a near end at the frame's edge), it steps east for it."""
    moves = {}
    for far in (None, {(5, 3): 1.0}):
        pol = BeliefPlanner()
        pol.reset(CFG, 1, 0)
        for t, y in enumerate((6, 5, 4)):
            pol.act(_obs(3, y, t))
        moves[far is not None] = tuple(int(v) for v in DELTAS[int(pol.act(_obs(3, 3, 3, far))[0])])
    assert moves[False] != (1, 0) and moves[True] == (1, 0), moves


def test_a_tour_whose_target_is_not_there_is_left() -> None:
    """A far sighting can make every target seem sighted when one is not (one cow read twice):
    the planner's tour (every target sighted) goes to it, finds the cell empty, and the search
    goes on instead of stepping about the empty cell (flight seed 70: 275 moves)."""
    cfg = GridConfig(width=7, height=7, n_targets=1)
    pol = BeliefPlanner()
    pol.reset(cfg, 1, 0)
    pol.act(_obs(3, 3, 0, {(5, 3): 1.0}))
    assert pol.in_tour[0], "the one target sighted: the tour starts"
    x, y, visited = 3, 3, set()
    for t in range(1, 12):
        a = int(pol.act(_obs(x, y, t))[0])
        x, y = x + int(DELTAS[a][0]), y + int(DELTAS[a][1])
        visited.add((x, y))
    assert not pol.in_tour[0]
    assert len(visited) >= 8, f"stepped about {sorted(visited)}"
