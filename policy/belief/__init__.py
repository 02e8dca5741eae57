"""The belief state (what the drone has seen, sighted, visited; for moving targets where a
sighted target can be now; under GPS the probabilistic versions) and the placement prior."""

from .prior import estimate_pair, estimate_prior, model_pair, model_prior
from .state import BELIEF_CHANNELS, PLANE_NAMES, BeliefState, motion_kernel, uniform_prior

__all__ = [
    "BELIEF_CHANNELS", "PLANE_NAMES", "BeliefState", "estimate_pair", "estimate_prior", "model_pair",
    "model_prior",
    "motion_kernel", "uniform_prior",
]
