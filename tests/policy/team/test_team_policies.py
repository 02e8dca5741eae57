"""Team policies (issue 29): N = 1 is today's belief planner, the team never bumps, the shared
belief's lossy link, and the team beats independent searchers."""

from __future__ import annotations

import numpy as np
import pytest

from policy.belief.shared import CommsModel
from policy.evaluation import evaluate
from policy.planner import BeliefPlanner
from policy.team import evaluate_team, make_team_policy
from sim.gridworld import GridConfig


def test_one_agent_team_is_todays_belief_exactly():
    cfg = GridConfig()
    single = evaluate(BeliefPlanner(), cfg, 60, 11, progress=False)
    team = evaluate_team(make_team_policy("belief"), cfg, 60, 11, 1, progress=False)
    assert np.array_equal(single.moves, team.makespan)
    assert np.array_equal(single.find_moves, team.find_moves)


@pytest.mark.parametrize("name", ["belief", "belief-independent", "lawnmower-strips"])
def test_team_policies_find_everything_without_bumps(name):
    r = evaluate_team(make_team_policy(name), GridConfig(), 40, 5, 3, progress=False)
    assert r.columns["success_pct"] == 100.0
    assert r.blocked.sum() == 0  # the policies' own separation: the world never had to refuse


def test_team_beats_independent_and_lossy_link_costs_little():
    cfg = GridConfig()
    team = evaluate_team(make_team_policy("belief"), cfg, 80, 9, 2, progress=False).makespan.mean()
    ind = evaluate_team(make_team_policy("belief-independent"), cfg, 80, 9, 2, progress=False).makespan.mean()
    lossy = evaluate_team(make_team_policy("belief", comms=CommsModel(delay=2, loss=0.3)), cfg, 80, 9, 2,
                          progress=False).makespan.mean()
    assert team < 0.85 * ind
    assert lossy < 1.1 * team


def test_comms_model_validates():
    with pytest.raises(ValueError, match="loss"):
        CommsModel(loss=1.0)
    with pytest.raises(ValueError, match="delay"):
        CommsModel(delay=-1)


def test_beacons_settle_finds_nobody_reported():
    # agent 1 stands on a cell agent 0's copy believes holds a sighted target: the copy moves it
    # to found before any message of agent 1 arrives (delay 5)
    from policy.belief.shared import SharedBelief

    sb = SharedBelief(GridConfig(), 1, 2, comms=CommsModel(delay=5))
    views = np.zeros((1, 2, 3, 3, 3), np.uint8)
    views[0, :, 2, 1, 1] = 1
    views[0, 0, 0, 1, 2] = 1  # agent 0 at (2, 2) sees a target at (3, 2)
    sb.update(views, np.array([[[2, 2], [7, 7]]]), np.array([0]), np.array([True]))
    assert sb.belief.sighted[0, 2, 3] == 1.0 and sb.belief.n_found[0] == 0.0
    views[0, 0, 0] = 0  # agent 0 at (1, 2) sees nothing; agent 1 stands on the target
    views[0, 1, 0, 1, 1] = 1
    sb.update(views, np.array([[[1, 2], [3, 2]]]), np.array([1]), np.array([True]))
    assert sb.belief.sighted[0, 2, 3] == 0.0 and sb.belief.found[0, 2, 3] == 1.0 and sb.belief.n_found[0] == 1.0
    assert sb.belief.n_found[1] == 1.0  # agent 1's own copy: its own find
