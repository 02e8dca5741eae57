"""Non-learned policies (NS, frontier, lawnmower, random) and the policy registry."""

from .frontier import FrontierPolicy
from .lawnmower import LawnmowerPolicy, serpentine
from .ns import NaivePolicy, VisitTracking
from .random_policy import RandomPolicy
from .registry import known_policies, make_policy, register_policy

__all__ = [
    "FrontierPolicy", "LawnmowerPolicy", "NaivePolicy", "RandomPolicy", "VisitTracking",
    "known_policies", "make_policy", "register_policy", "serpentine",
]
