"""The companion computer: MAVLink link, GPS estimator, probabilistic map, camera detector,
and the policy service that flies the search.

Rooms by concern: `dialects/` (what each autopilot family needs: PX4, ArduPilot), `camera/`
(frame sources: a MAVLink camera component, a video stream), `preflight.py` (the
companion-loss failsafe check), `journal.py` / `resume.py` (a restarted companion goes on)."""

from .detector import DetectorConfig, cell_fractions, frame_to_view
from .estimator import EstimatorConfig, GpsEstimator, PositionPosterior
from .images import FrameAssembler, decode_png
from .link import CommandRejected, LinkError, Telemetry, VehicleLink
from .probmap import ProbabilisticVisitationMap, cell_probabilities
from .service import PolicyService, SearchLog, SearchSpec

__all__ = [
    "CommandRejected", "DetectorConfig", "EstimatorConfig", "FrameAssembler", "GpsEstimator", "LinkError",
    "PolicyService", "PositionPosterior", "ProbabilisticVisitationMap", "SearchLog", "SearchSpec",
    "Telemetry", "VehicleLink", "cell_fractions", "cell_probabilities", "decode_png", "frame_to_view",
]
