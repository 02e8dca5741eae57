"""A kinematic point-mass flight model: velocity-limited, acceleration-limited position
tracking with no attitude dynamics. For lock-step runs of many vehicles where the
PyBullet airframe would be the bottleneck; same contract as the quadrotor."""

from __future__ import annotations

import numpy as np

from .model import VehicleState


class KinematicVehicle:
    def __init__(
        self,
        max_speed: float = 5.0,
        max_climb: float = 2.0,
        max_accel: float = 4.0,
        position_gain: float = 1.2,
    ) -> None:
        self._s = VehicleState()
        self.max_speed, self.max_climb, self.max_accel, self.kp = max_speed, max_climb, max_accel, position_gain
        self._target: np.ndarray | None = None
        self._speed: float | None = None
        self._vel_cmd: np.ndarray | None = None
        self._yaw: float | None = None
        self._landing = False

    @property
    def state(self) -> VehicleState:
        return self._s

    def arm(self) -> bool:
        if self._s.armed:
            return True
        self._s.armed = True
        self._target = self._s.position_ned.copy()
        return True

    def disarm(self, force: bool = False) -> bool:
        if not self._s.landed and not force:
            return False
        self._s.armed = False
        self._target = None
        self._vel_cmd = None
        self._landing = False
        return True

    def set_position_target(self, position_ned, yaw=None, speed=None) -> None:
        self._target = np.asarray(position_ned, dtype=float).copy()
        self._speed, self._yaw, self._vel_cmd, self._landing = speed, yaw, None, False

    def set_velocity_target(self, velocity_ned, yaw_rate: float = 0.0) -> None:
        self._vel_cmd = np.asarray(velocity_ned, dtype=float).copy()
        self._target, self._landing = None, False

    def land(self) -> None:
        self._landing = True
        self._vel_cmd = None
        self._target = None

    def step(self, dt: float) -> None:
        s = self._s
        s.time_s += dt
        if not s.armed:
            s.velocity_ned[:] = 0.0
            return
        if self._landing:
            want = np.array([0.0, 0.0, 0.7])
        elif self._vel_cmd is not None:
            want = self._vel_cmd.copy()
        elif self._target is not None:
            want = self.kp * (self._target - s.position_ned)
        else:
            want = np.zeros(3)
        horiz = np.linalg.norm(want[:2])
        vmax = min(self.max_speed, self._speed or self.max_speed)
        if horiz > vmax:
            want[:2] *= vmax / horiz
        want[2] = np.clip(want[2], -self.max_climb, self.max_climb)
        dv = want - s.velocity_ned
        lim = self.max_accel * dt
        n = np.linalg.norm(dv)
        if n > lim:
            dv *= lim / n
        s.velocity_ned += dv
        s.position_ned += s.velocity_ned * dt
        if s.position_ned[2] >= 0.0:
            s.position_ned[2] = 0.0
            s.velocity_ned[2] = min(s.velocity_ned[2], 0.0)
            s.landed = True
            if self._landing:
                self.disarm()
        else:
            s.landed = False
        if self._yaw is not None:
            s.attitude_rpy[2] = self._yaw
        s.battery_remaining = max(0.0, s.battery_remaining - dt / 1800.0)
        s.battery_voltage = 14.0 + 2.8 * s.battery_remaining

    def close(self) -> None:
        pass
