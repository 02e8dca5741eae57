"""Ground truth synthesis (paper Section IV): CU, optimal PT (Held-Karp) and lookahead PT."""

from .bruteforce import intercept_scan, lookahead_bruteforce, pt_bruteforce
from .legs import step_towards
from .lookahead import intercept, lookahead_dp
from .plans import PlanPolicy, Plans, optimal_lengths, solve
from .pt import held_karp, path_lengths

__all__ = [
    "Plans", "PlanPolicy", "held_karp", "intercept", "intercept_scan", "lookahead_bruteforce",
    "lookahead_dp", "optimal_lengths", "path_lengths", "pt_bruteforce", "solve", "step_towards",
]
