"""The link to the autopilot: a thin MAVLink connection (pymavlink), what each autopilot family
needs (`dialects/`: PX4, ArduPilot) and the companion's own .tlog."""

from .connection import CommandRejected, LinkError, Telemetry, VehicleLink, WrongAutopilot

__all__ = ["CommandRejected", "LinkError", "Telemetry", "VehicleLink", "WrongAutopilot"]
