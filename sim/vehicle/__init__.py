"""Simulated airframes: the FlightModel contract and its implementations."""

from .kinematic import KinematicVehicle
from .model import FlightModel, VehicleState

__all__ = ["FlightModel", "KinematicVehicle", "VehicleState"]
