"""Cooperative search with several UAVs (issue 29): team policies over the team grid world
(sim.gridworld.team) and their evaluation. docs/fleet.md."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sim.gridworld import GridConfig

from ..belief.shared import CommsModel
from .base import TeamObservation, TeamPolicy, separate, team_observe
from .runner import TeamResult, evaluate_team

#: the team policies by name, for `eval --agents` and `quality --agents`
TEAM_POLICIES: dict[str, str] = {
    "belief": "the belief planner on the team's shared belief, goals by sequential greedy claims",
    "belief-independent": "N independent single-agent belief planners, each with its own belief",
    "lawnmower-strips": "the field cut in N strips, each swept by one agent (boustrophedon)",
    "searchnet": "the search network, decentralised: each agent on the shared belief, its own cell and its "
                 "teammates' (DAgger from the team planner; shipped team checkpoint or --checkpoint)",
}


def team_searchnet_checkpoint(cfg: GridConfig | None = None) -> Path:
    """The shipped team network for the field: the one trained on its size where there is one
    (searchnet_team_static_random_20x20), else the 10 x 10 one (it runs on any size)."""
    from ..nn import shipped_checkpoint

    if cfg is not None:
        sized = shipped_checkpoint(f"searchnet_team_static_random_{cfg.width}x{cfg.height}")
        if sized.is_file():
            return sized
    return shipped_checkpoint("searchnet_team_static_random")


def make_team_policy(name: str, comms: CommsModel | None = None, cfg: GridConfig | None = None,
                     checkpoint: str | Path | None = None, **kw: Any) -> TeamPolicy:
    """A fresh team policy by name; comms (the team's sharing model) for `belief` and
    `searchnet`; cfg and checkpoint pick the network for `searchnet`."""
    if name == "searchnet":
        from ..searchnet.team import load_team_searchnet

        path = Path(checkpoint) if checkpoint is not None else team_searchnet_checkpoint(cfg)
        pol = load_team_searchnet(path, comms=comms, **kw)
        if not pol.model.cfg.team_planes:  # a single-agent network: N = 1 as today's `searchnet`
            from ..baselines.registry import make_policy

            pol.single = make_policy("searchnet", cfg, checkpoint=path)
        return pol
    if checkpoint is not None:
        raise ValueError(f"team policy {name!r} takes no checkpoint")
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
           "make_team_policy", "separate", "team_observe", "team_searchnet_checkpoint"]
