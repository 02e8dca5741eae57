"""The flight's companion knows its finds (Observation.found_now) and shows a found target in
the view's centre slot where it stands on the cell the agent was told: under an uncertain
position the belief counts those finds exactly and puts their found mass on that cell; the
planner plans from where the belief, after the view's evidence, puts the agent (flight seeds
25 and 58: back and forth beside cows for 8-12 moves)."""

from __future__ import annotations

import numpy as np
import pytest

from policy.base import Observation
from policy.belief import BeliefState
from policy.planner import BeliefPlanner
from sim.gridworld import DELTAS, GridConfig

CFG = GridConfig(width=7, height=7, n_targets=3)


def _view(x: int, y: int, targets: tuple[tuple[int, int], ...] = ()) -> np.ndarray:
    """The (3, 3, 3) view around (x, y) with targets in the given slots (dx, dy)."""
    v = np.zeros((3, 3, 3), np.uint8)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if not (0 <= x + dx < CFG.width and 0 <= y + dy < CFG.height):
                v[1, dy + 1, dx + 1] = 1
    for dx, dy in targets:
        v[0, dy + 1, dx + 1] = 1
    v[2, 1, 1] = 1
    return v


def _obs(x: int, y: int, t: int, prob: dict[tuple[int, int], float], targets=(), found_now: float | None = None,
         valid=None) -> Observation:
    p = np.zeros((1, CFG.height, CFG.width), np.float32)
    for (cx, cy), w in prob.items():
        p[0, cy, cx] = w
    return Observation(views=_view(x, y, targets)[None], maps=None, positions=np.array([[x, y]]),
                       valid=np.ones((1, 4), bool) if valid is None else valid, t=np.array([t]),
                       active=np.array([True]), position_prob=p,
                       found_now=None if found_now is None else np.array([found_now]))


def test_a_find_the_companion_made_counts_once_on_the_told_cell() -> None:
    spread = {(3, 3): 0.6, (3, 4): 0.4}
    # the belief's own expectation: a part-find, spread over the posterior
    guess = BeliefState(CFG, 1)
    guess.update(_obs(3, 3, 0, spread, targets=((0, 0),)))
    assert 0.0 < float(guess.n_found[0]) < 1.0 or guess.found[0, 4, 3] > 0.0
    # told by the companion: one find, on the told cell (3, 3)
    b = BeliefState(CFG, 1)
    b.update(_obs(3, 3, 0, spread, targets=((0, 0),), found_now=1.0))
    assert float(b.n_found[0]) == 1.0
    assert b.found[0, 3, 3] == pytest.approx(1.0, abs=1e-6)
    assert float(b.found.sum()) == pytest.approx(1.0, abs=1e-6)
    # back over it later (shown again in the centre, no new find): still one
    b.update(_obs(3, 2, 1, {(3, 2): 1.0}))
    b.update(_obs(3, 3, 2, spread, targets=((0, 0),), found_now=0.0))
    assert float(b.n_found[0]) == 1.0
    with pytest.raises(ValueError, match="found_now"):
        b.update(_obs(3, 3, 3, spread, found_now=-1.0))


def test_the_planner_plans_from_where_the_view_puts_the_agent() -> None:
    """Told (3, 3), but the posterior half on (3, 4); a target was sighted on (3, 3) earlier.
    Now the view shows a target in the north slot and none under the camera: the agent is on
    (3, 4), with the target north of it. Planned from the told cell, the target is "here"
    (standing still recovers nothing new: its goal is any other cell); from the belief's cell
    the goal is the target, north."""
    half = {(3, 3): 0.5, (3, 4): 0.5}
    for seed in range(5):
        pl = BeliefPlanner()
        pl.reset(CFG, 1, seed)
        pl.act(_obs(3, 4, 0, {(3, 4): 1.0}, targets=((0, -1),), found_now=0.0))  # the target on (3, 3)
        assert pl.belief.sighted[0, 3, 3] > 0.9
        a = int(pl.act(_obs(3, 3, 1, half, targets=((0, -1),), found_now=0.0))[0])
        assert pl.belief.position[0, 4, 3] > 0.9, "the view says (3, 4)"
        assert tuple(DELTAS[a]) == (0, -1), "north, onto the target"
        assert tuple(pl._goal(np.array([[3, 4]]))[0]) == (3, 3)
        assert tuple(pl._goal(np.array([[3, 3]]))[0]) != (3, 3), "from the told cell: anywhere but the target"
