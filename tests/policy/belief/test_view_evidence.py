"""The view as evidence about the position (BeliefState view_evidence) and the reopened search
when a view missed a target (BeliefState._reopen_if_exhausted).

Both exist for the flight, where the companion's position is a GPS posterior and its camera can
be off its cell: a found target seen one cell east from the believed cell must not become a
phantom unfound target on the believed cell (the planner went back and forth for it), and a
target the view missed must not leave the planner with nothing to look for."""

from __future__ import annotations

import numpy as np

from policy.base import Observation
from policy.belief import BeliefState
from policy.belief.state import VIEW_EPS
from sim.gridworld import GridConfig

CFG = GridConfig(width=6, height=5, n_targets=3)


def _view(x: int, y: int, targets: set[tuple[int, int]], cfg: GridConfig = CFG) -> np.ndarray:
    """The (3, 3, 3) view from cell (x, y) of static targets at `targets`."""
    v = np.zeros((3, 3, 3), np.uint8)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            cx, cy = x + dx, y + dy
            if not (0 <= cx < cfg.width and 0 <= cy < cfg.height):
                v[1, dy + 1, dx + 1] = 1
            elif (cx, cy) in targets:
                v[0, dy + 1, dx + 1] = 1
    v[2, 1, 1] = 1
    return v


def _obs(x: int, y: int, view: np.ndarray, t: int, p: np.ndarray | None = None) -> Observation:
    return Observation(views=view[None], maps=None, positions=np.array([[x, y]]),
                       valid=np.ones((1, 4), bool), t=np.array([t]), active=np.array([True]),
                       position_prob=None if p is None else p[None].astype(np.float32))


def test_view_likelihood_equals_a_cellwise_product():
    rng = np.random.default_rng(4)
    b = BeliefState(CFG, 1)
    b.target = rng.random((1, CFG.height, CFG.width)).astype(np.float32) * 0.6
    b.found = rng.random((1, CFG.height, CFG.width)).astype(np.float32) * 0.3
    slots = rng.integers(0, 2, (1, 3, 3))
    got = b._view_likelihood(slots)[0]
    occ = np.clip(b.target[0] + b.found[0], VIEW_EPS, 1 - VIEW_EPS)
    want = np.zeros((CFG.height, CFG.width))
    for y in range(CFG.height):
        for x in range(CFG.width):
            like = 1.0
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    cy, cx = y + dy, x + dx
                    if 0 <= cy < CFG.height and 0 <= cx < CFG.width:
                        like *= occ[cy, cx] if slots[0, dy + 1, dx + 1] else 1 - occ[cy, cx]
                    elif slots[0, dy + 1, dx + 1]:  # a target shown off the grid: no such place
                        like *= VIEW_EPS
            want[y, x] = like
    np.testing.assert_allclose(got, want / want.max(), rtol=1e-4)


def _found_east_then_seen_from_west(view_evidence: bool) -> BeliefState:
    """A target at (3, 2) found by standing on it; then the agent, believed at (2, 2) with 0.7
    and at (1, 2) with 0.3, sees it in the east slot (it is truly at (2, 2))."""
    b = BeliefState(CFG, 1, view_evidence=view_evidence)
    targets = {(3, 2), (0, 0), (5, 4)}
    b.update(_obs(3, 2, _view(3, 2, targets), 0))
    assert b.n_found[0] == 1.0
    p = np.zeros((CFG.height, CFG.width))
    p[2, 2], p[2, 1] = 0.7, 0.3
    b.update(_obs(2, 2, _view(2, 2, targets), 1, p))
    return b


def test_a_found_target_seen_again_makes_no_phantom_on_the_believed_cell():
    with_evidence = _found_east_then_seen_from_west(True)
    without = _found_east_then_seen_from_west(False)
    # without: from (1, 2) the target east would stand on (2, 2), where nobody expected one, so
    # 0.3 of a new target lands there; with: a view that shows the found target where it is
    # puts the agent on (2, 2), and nothing new is believed
    assert without.sighted[0, 2, 2] > 0.25
    assert with_evidence.sighted[0, 2, 2] < 0.05
    assert with_evidence.position[0, 2, 2] > 0.95
    for b in (with_evidence, without):
        np.testing.assert_allclose(b.target.sum(), CFG.n_targets - b.n_found[0], rtol=1e-4)


def test_exact_positions_ignore_view_evidence():
    a, b = BeliefState(CFG, 1, view_evidence=True), BeliefState(CFG, 1, view_evidence=False)
    targets = {(3, 2), (0, 0), (5, 4)}
    for t, (x, y) in enumerate([(0, 4), (1, 4), (1, 3), (2, 3), (3, 3), (3, 2)]):
        obs = _obs(x, y, _view(x, y, targets), t)
        a.update(obs)
        b.update(obs)
    for name in ("visited", "seen", "target", "found", "n_found"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_a_missed_target_reopens_the_cells_not_visited():
    """The view never shows the target at (5, 4) (a camera off its cell): once every cell has
    been seen with it unsighted, the cells not visited take the remaining target again."""
    b = BeliefState(CFG, 1)
    shown = {(0, 0)}  # (5, 4) and (4, 1) are there but never shown
    path = [(1, 1), (4, 1), (4, 3), (1, 3)]
    for t, (x, y) in enumerate(path):
        b.update(_obs(x, y, _view(x, y, shown), t))
    assert b.seen.min() == 1.0 or b._reopened  # every cell was shown once
    # (4, 1) was visited, so its target counted as found: 1 + (0, 0) sighted, 1 left unsighted
    assert b.unsighted[0] > 0.5
    t = b.target[0]
    assert abs(t.sum() - (CFG.n_targets - b.n_found[0])) < 1e-4
    visited = b.visited[0] > 0.5
    assert (t[visited] < 1e-6).all()
    assert (t[~visited & (b.sighted[0] < 0.5)] > 0).all()  # spread over the cells not visited


def test_reopening_never_happens_with_a_perfect_view():
    rng = np.random.default_rng(0)
    targets = {(3, 2), (0, 0), (5, 4)}
    b = BeliefState(CFG, 1)
    x, y = 2, 2
    for t in range(80):
        b.update(_obs(x, y, _view(x, y, targets), t))
        assert not b._reopened
        x = int(np.clip(x + rng.integers(-1, 2), 0, CFG.width - 1))
        y = int(np.clip(y + rng.integers(-1, 2), 0, CFG.height - 1))




def test_under_a_gps_posterior_a_nearly_dry_pool_reopens_but_an_exact_one_does_not():
    """Soft positions never make seen exactly 1: a target believed unsighted with under
    SOFT_DRY of the prior left unseen reopens the cells not visited. With exact positions the
    same state keeps the last unseen cells as the only places to look (they are)."""
    from policy.belief.state import SOFT_DRY

    for uncertain in (True, False):
        b = BeliefState(CFG, 1)
        b.seen[:] = 1.0 - SOFT_DRY / 2  # every cell all but seen
        b.visited[0, 2, :] = 1.0  # one row flown
        b._crisp = False
        b._uncertain[:] = uncertain
        b._reopen_if_exhausted()
        assert b._reopened == uncertain
        if uncertain:
            np.testing.assert_allclose(b.seen[0, 2], 1.0 - SOFT_DRY / 2)  # the row flown stays seen
            assert (b.seen[0, [0, 1, 3, 4]] == 0.0).all()  # the rest is open again
            assert (b.prior * (1.0 - b.seen[0])).sum() > 0.75  # the pool has somewhere to be
        else:
            assert (b.seen[0] == 1.0 - SOFT_DRY / 2).all()
