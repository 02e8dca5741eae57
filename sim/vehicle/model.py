"""The contract between a flight model and the MAVLink endpoint.

The endpoint (sim.mavlink) only sees this interface, so the PyBullet quadrotor and the
kinematic point mass are interchangeable: the first for fidelity, the second for fast
lock-step batch runs. Frames: local NED about the home position, metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class VehicleState:
    """True state of the airframe (the GPS model adds the noise, never this)."""

    time_s: float = 0.0
    position_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: roll, pitch, yaw (rad), and body rates p, q, r (rad/s)
    attitude_rpy: np.ndarray = field(default_factory=lambda: np.zeros(3))
    body_rates: np.ndarray = field(default_factory=lambda: np.zeros(3))
    armed: bool = False
    landed: bool = True
    battery_voltage: float = 16.8
    battery_remaining: float = 1.0  # 0..1


class FlightModel(Protocol):
    """What a simulated airframe with its own position controller must offer."""

    @property
    def state(self) -> VehicleState: ...

    def arm(self) -> bool:
        """Spin up; return False (and stay disarmed) when arming is not allowed now."""

    def disarm(self, force: bool = False) -> bool:
        """Stop motors; refuse in flight unless forced."""

    def set_position_target(
        self, position_ned: np.ndarray, yaw: float | None = None, speed: float | None = None
    ) -> None:
        """Fly to and hold a local NED position (z negative up), at most `speed` m/s."""

    def set_velocity_target(self, velocity_ned: np.ndarray, yaw_rate: float = 0.0) -> None:
        """Track a NED velocity (offboard/guided velocity control)."""

    def land(self) -> None:
        """Descend at the current horizontal position and disarm on touchdown."""

    def step(self, dt: float) -> None:
        """Advance the simulation by dt seconds (the model sub-steps internally)."""

    def close(self) -> None: ...
