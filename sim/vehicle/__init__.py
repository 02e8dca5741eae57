"""Simulated airframes and sensors: the FlightModel contract, the PyBullet quadrotor, the
kinematic point mass, the field with its cattle, the downward camera and the GPS."""

from .camera import ALTITUDE_M, DownCamera, ViewRenderer, WorldState, render_view
from .field import Field, cell_to_enu
from .geo import HomePosition, from_e7, to_e7
from .gps import GpsConfig, GpsFix, GpsModel
from .kinematic import KinematicVehicle
from .model import FlightModel, VehicleState
from .quadrotor import Airframe, PyBulletQuadrotor

__all__ = [
    "ALTITUDE_M", "Airframe", "DownCamera", "Field", "FlightModel", "GpsConfig", "GpsFix", "GpsModel",
    "HomePosition", "KinematicVehicle", "PyBulletQuadrotor", "VehicleState", "ViewRenderer",
    "WorldState", "cell_to_enu", "from_e7", "render_view", "to_e7",
]
