"""The companion computer: MAVLink link, GPS estimator, probabilistic map, policy service."""

from .estimator import EstimatorConfig, GpsEstimator, PositionPosterior
from .probmap import ProbabilisticVisitationMap, cell_probabilities

__all__ = [
    "EstimatorConfig",
    "GpsEstimator",
    "PositionPosterior",
    "ProbabilisticVisitationMap",
    "cell_probabilities",
]
