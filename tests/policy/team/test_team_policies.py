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
    lossy = evaluate_team(make_team_policy("belief", comms=CommsModel(delay=2, loss=0.3, history=4)), cfg, 80, 9, 2,
                          progress=False).makespan.mean()
    assert team < 0.85 * ind
    assert team <= lossy < 1.25 * team


def test_comms_model_validates():
    with pytest.raises(ValueError, match="loss"):
        CommsModel(loss=1.0)
    with pytest.raises(ValueError, match="delay"):
        CommsModel(delay=-1)
