"""The companion computer: it flies the search over a real MAVLink link to any autopilot.

Rooms by concern (one sub-package each, so a newcomer finds the room by its name):
- `link/`: the thin MAVLink connection (`connection.py`), what each autopilot family needs
  (`dialects/`: PX4, ArduPilot) and the companion's own `.tlog`;
- `camera/`: frame sources (a MAVLink camera component, an RTP/H.264 video stream);
- `detection/`: a frame to what the policy sees (the detector, the view I at any level, the
  memory of which blobs are targets already found);
- `localisation/`: where the vehicle is (the GPS estimator, the telemetry intake, the GPS-free
  registrations on the field's edge and on found targets);
- `service/`: the search itself (the policy loop, the pilot, the height flown, the fence, the
  preflight failsafe check, the bring-down on every exit, the journal a restarted companion
  resumes from, the probabilistic map and the search's data)."""

from .camera import FrameAssembler, decode_png
from .detection.detector import DetectorConfig, cell_fractions, frame_to_view
from .link.connection import CommandRejected, LinkError, Telemetry, VehicleLink
from .localisation.estimator import EstimatorConfig, GpsEstimator, PositionPosterior
from .service.policy_service import PolicyService, SearchLog, SearchSpec
from .service.probmap import ProbabilisticVisitationMap, cell_probabilities

__all__ = [
    "CommandRejected", "DetectorConfig", "EstimatorConfig", "FrameAssembler", "GpsEstimator", "LinkError",
    "PolicyService", "PositionPosterior", "ProbabilisticVisitationMap", "SearchLog", "SearchSpec",
    "Telemetry", "VehicleLink", "cell_fractions", "cell_probabilities", "decode_png", "frame_to_view",
]
