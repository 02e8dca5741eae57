"""A fleet's shared finds (autopilot_bridge.localisation.team_finds): a blob a vehicle's own
finds do not explain is matched against its teammates' finds in the field frame, and a target
seen a cell off a teammate's find is that find unless the find shows beside it."""

from __future__ import annotations

import numpy as np

from autopilot_bridge.localisation.estimator import GpsEstimator
from autopilot_bridge.localisation.team_finds import TeamFind, TeamFinds, TeamFoundTargets
from autopilot_bridge.service.search_data import SearchSpec
from sim.gridworld import GridConfig, cell_to_ned
from sim.gridworld.geodesy import HomePosition

FLAT = (False, False)


def _memory() -> tuple[TeamFoundTargets, TeamFind]:
    spec = SearchSpec(HomePosition(51.4545, -2.5879, 30.0), GridConfig(width=20, height=20, n_targets=10))
    team = TeamFinds()
    find = TeamFind(vehicle=0, t=10.0, ne=cell_to_ned(np.array([10, 7])), var_ne=np.full(2, 0.1), told=(10, 7))
    team.add(find)
    # vehicle 1's memory: assign_team reads the grid, the camera's height and field of view only
    return TeamFoundTargets(spec, GpsEstimator(), None, team, vehicle=1), find  # type: ignore[arg-type]


def test_a_target_a_cell_off_a_teammates_find_is_that_find_unless_the_find_shows_beside_it() -> None:
    tf, find = _memory()
    cam = cell_to_ned(np.array([10, 6]))  # it believes it is over (10, 6); the find is a cell south
    sure = [(1.0, cam, np.full(2, 0.01))]  # its posterior: one hypothesis, sure of itself (and a cell off)
    under = np.array([0.1, 0.2])
    # the target under the camera, and nothing where the find would show if this frame were right
    assert tf.assign_team([under], [FLAT], [find], sure) == [0]
    # the find shows a cell south in the frame too: the one under the camera is a new target
    beside = find.ne - cam + np.array([0.1, -0.1])
    assert tf.assign_team([under, beside], [FLAT, FLAT], [find], sure) == [None, 0]
    # seen where its finder put it: the find; two cells off: not it
    assert tf.assign_team([find.ne - cam + 0.2], [FLAT], [find], sure) == [0]
    assert tf.assign_team([find.ne - cam + np.array([4.0, 0.0])], [FLAT], [find], sure) == [None]


def test_a_posterior_split_between_two_cells_is_weighed_per_hypothesis() -> None:
    tf, find = _memory()
    # the camera truly over (10, 4), its posterior split between that (0.45) and a cell south,
    # (10, 5) (0.55); a new target a cell south of the truth, at (10, 5), two cells off the find
    # at (10, 7). Placed by the likelier hypothesis alone, with the mixture's spread, it looked
    # like the find (seed 8: found 44 rounds later); weighed per hypothesis it is new
    right, wrong = cell_to_ned(np.array([10, 4])), cell_to_ned(np.array([10, 5]))
    split = [(0.45, right, np.full(2, 0.1)), (0.55, wrong, np.full(2, 0.1))]
    new_cow = cell_to_ned(np.array([10, 5])) - right
    assert tf.assign_team([new_cow], [FLAT], [find], split) == [None]
    # a cow on the find's own cell in the likelier hypothesis' frame: the find
    assert tf.assign_team([find.ne - wrong + 0.1], [FLAT], [find], split) == [0]


def test_a_vehicles_own_finds_are_not_its_teammates() -> None:
    tf, find = _memory()
    assert len(tf) == 1  # the teammate's find counts: register_known looks at the frames
    tf.team.add(TeamFind(vehicle=1, t=20.0, ne=cell_to_ned(np.array([3, 3])), var_ne=np.full(2, 0.1), told=(3, 3)))
    assert len(tf) == 1 and tf.is_team(1_000_000) and not tf.is_team(0) and not tf.is_team(None)
    np.testing.assert_array_equal(tf.team_landmark(1_000_000)[0], find.ne)
