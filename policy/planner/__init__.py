"""The belief-space planner `belief`: exact tour once every target is sighted, otherwise
information (targets revealed or recovered) per step of travel."""

from .planner import BeliefPlanner, PlannerParams, resolve_prior

__all__ = ["BeliefPlanner", "PlannerParams", "resolve_prior"]
