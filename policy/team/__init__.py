"""Cooperative search with several UAVs (issue 29): team policies over the team grid world
(sim.gridworld.team) and their evaluation. docs/fleet.md."""

from __future__ import annotations

from typing import Any

from ..belief.shared import CommsModel
from .base import TeamObservation, TeamPolicy, separate, team_observe
from .runner import TeamResult, evaluate_team

#: the team policies by name, for `eval --agents` and `quality --agents`
TEAM_POLICIES: dict[str, str] = {
    "belief": "the belief planner on the team's shared belief, goals by sequential greedy claims",
    "belief-independent": "N independent single-agent belief planners, each with its own belief",
    "lawnmower-strips": "the field cut in N strips, each swept by one agent (boustrophedon)",
}


def make_team_policy(name: str, comms: CommsModel | None = None, **kw: Any) -> TeamPolicy:
    """A fresh team policy by name; comms (the belief team's sharing model) only for `belief`."""
    if name == "belief":
        from .planner import TeamBeliefPlanner

        return TeamBeliefPlanner(comms=comms, **kw)
    if name == "belief-independent":
        from ..planner import BeliefPlanner
        from .baselines import IndependentTeam

        return IndependentTeam(BeliefPlanner(**kw))
    if name == "lawnmower-strips":
        from .baselines import StripLawnmower

        return StripLawnmower()
    raise KeyError(f"unknown team policy {name!r}; known: {', '.join(TEAM_POLICIES)}")


__all__ = ["CommsModel", "TEAM_POLICIES", "TeamObservation", "TeamPolicy", "TeamResult", "evaluate_team",
           "make_team_policy", "separate", "team_observe"]
