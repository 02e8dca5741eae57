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
    var = np.full(2, 0.01)  # this vehicle's posterior: sure of itself (and a cell off)
    cam = cell_to_ned(np.array([10, 6]))  # it believes it is over (10, 6); the find is a cell south
    under = cam + np.array([0.1, 0.2])
    # the target under the camera, and nothing where the find would show if this frame were right
    assert tf.assign_team([under], var, [FLAT], [find], cam) == [0]
    # the find shows a cell south in the frame too: the one under the camera is a new target
    assert tf.assign_team([under, find.ne + np.array([0.1, -0.1])], var, [FLAT, FLAT], [find], cam) == [None, 0]
    # without knowing where the camera is (no view to check) the lattice prior decides: new
    assert tf.assign_team([under], var, [FLAT], [find], None) == [None]
    # seen where its finder put it: the find; two cells off: not it
    assert tf.assign_team([find.ne + 0.2], var, [FLAT], [find], cam) == [0]
    assert tf.assign_team([find.ne + np.array([4.0, 0.0])], var, [FLAT], [find], cam) == [None]


def test_a_vehicles_own_finds_are_not_its_teammates() -> None:
    tf, find = _memory()
    assert len(tf) == 1  # the teammate's find counts: register_known looks at the frames
    tf.team.add(TeamFind(vehicle=1, t=20.0, ne=cell_to_ned(np.array([3, 3])), var_ne=np.full(2, 0.1), told=(3, 3)))
    assert len(tf) == 1 and tf.is_team(1_000_000) and not tf.is_team(0) and not tf.is_team(None)
    np.testing.assert_array_equal(tf.team_landmark(1_000_000)[0], find.ne)
