"""Non-learned policies and the policy registry."""

from .registry import known_policies, make_policy, register_policy
from .simple import FrontierPolicy, LawnmowerPolicy, NaivePolicy, RandomPolicy, serpentine

__all__ = [
    "FrontierPolicy", "LawnmowerPolicy", "NaivePolicy", "RandomPolicy", "known_policies",
    "make_policy", "register_policy", "serpentine",
]
