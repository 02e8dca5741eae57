"""A quadrotor rigid body in PyBullet (headless DIRECT), flown by the cascaded controller.

Four rotors in X configuration each apply a thrust kf * w^2 at their arm's tip and a drag
torque km * w^2 about the body z axis (alternating directions); motor speeds follow their
commands with a first-order lag; the body feels gravity and linear air drag. 240 Hz physics,
the controller at the same rate. Implements the FlightModel contract (sim/vehicle/model.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from .controller import CascadedController, Gains
from .frames import enu_to_ned, ned_to_enu, ned_yaw_to_enu, rpy_flu_to_frd
from .model import VehicleState

PHYSICS_HZ = 240


@dataclass(frozen=True)
class Airframe:
    mass: float = 1.5  # kg
    arm: float = 0.25  # m, centre to rotor
    kf: float = 1.2e-5  # N / (rad/s)^2
    km: float = 2.0e-7  # N m / (rad/s)^2
    max_omega: float = 1100.0  # rad/s: ~2.1 thrust-to-weight
    motor_tau: float = 0.02  # s
    drag: float = 0.25  # N / (m/s), linear
    size: tuple[float, float, float] = (0.35, 0.35, 0.08)


class PyBulletQuadrotor:
    def __init__(
        self,
        airframe: Airframe | None = None,
        gains: Gains | None = None,
        start_ned: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0),
        client: int | None = None,
    ) -> None:
        self.af = airframe or Airframe()
        self.cid = p.connect(p.DIRECT) if client is None else client
        self._own_client = client is None
        p.setGravity(0, 0, -9.81, physicsClientId=self.cid)
        p.setTimeStep(1.0 / PHYSICS_HZ, physicsClientId=self.cid)
        ground = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=self.cid)
        self.ground = p.createMultiBody(0, ground, physicsClientId=self.cid)
        half = [s / 2 for s in self.af.size]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=self.cid)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=[0.2, 0.2, 0.25, 1], physicsClientId=self.cid)
        start = ned_to_enu(np.asarray(start_ned, dtype=float))
        start[2] = max(start[2], half[2])
        north = p.getQuaternionFromEuler([0, 0, np.pi / 2])  # nose north, as a pilot sets it down
        self.body = p.createMultiBody(self.af.mass, col, vis, start.tolist(), north, physicsClientId=self.cid)
        p.changeDynamics(self.body, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=self.cid)
        m, (a, b, c) = self.af.mass, self.af.size
        self.J = np.diag([m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12])
        self.ctrl = CascadedController(self.af.mass, self.J, gains)
        d = self.af.arm / np.sqrt(2)
        # rotor positions (FLU) and spin directions (+1 CCW seen from above gives -z reaction)
        self.rotors = np.array([[d, -d, 0], [-d, d, 0], [d, d, 0], [-d, -d, 0]], dtype=float)
        self.spin = np.array([1, 1, -1, -1], dtype=float)
        alloc = np.vstack([
            np.ones(4),
            self.rotors[:, 1],  # roll torque = y * F
            -self.rotors[:, 0],  # pitch torque = -x * F
            self.spin * self.af.km / self.af.kf,
        ])
        self._alloc_inv = np.linalg.inv(alloc)
        self.omega = np.zeros(4)
        self._s = VehicleState()
        self._mode = "idle"  # idle | position | velocity | land
        self._target_enu = start.copy()
        self._vel_enu = np.zeros(3)
        self._speed: float | None = None
        self._yaw_enu = np.pi / 2  # facing north
        self.time = 0.0
        self.motor_thrusts = np.zeros(4)
        self._update_state()

    # -- FlightModel ---------------------------------------------------------------------
    @property
    def state(self) -> VehicleState:
        return self._s

    def arm(self) -> bool:
        if self._s.armed:
            return True
        if not self._s.landed:
            return False
        self._s.armed = True
        self.ctrl.reset()
        pos, _ = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        self._target_enu = np.array(pos)
        self._mode = "idle"
        return True

    def disarm(self, force: bool = False) -> bool:
        if not self._s.landed and not force:
            return False
        self._s.armed = False
        self._mode = "idle"
        self.omega[:] = 0.0
        return True

    def set_position_target(self, position_ned, yaw=None, speed=None) -> None:
        self._target_enu = ned_to_enu(np.asarray(position_ned, dtype=float))
        if yaw is not None and np.isfinite(yaw):
            self._yaw_enu = ned_yaw_to_enu(float(yaw))
        self._speed = speed
        self._mode = "position"

    def set_velocity_target(self, velocity_ned, yaw_rate: float = 0.0) -> None:
        self._vel_enu = ned_to_enu(np.asarray(velocity_ned, dtype=float))
        self._mode = "velocity"

    def land(self) -> None:
        self._mode = "land"

    def step(self, dt: float) -> None:
        for _ in range(max(1, int(round(dt * PHYSICS_HZ)))):
            self._substep()
        self._update_state()

    def close(self) -> None:
        if self._own_client and p.isConnected(self.cid):
            p.disconnect(self.cid)

    # -- physics -------------------------------------------------------------------------
    def _substep(self) -> None:
        h = 1.0 / PHYSICS_HZ
        pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.cid)
        pos, lin, ang = np.array(pos), np.array(lin), np.array(ang)
        rot = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        omega_b = rot.T @ ang
        if self._s.armed and self._mode != "idle":
            if self._mode == "position":
                vel_sp = self.ctrl.velocity_setpoint(pos, self._target_enu, self._speed)
            elif self._mode == "velocity":
                vel_sp = self._vel_enu
            else:  # land: hold horizontal position, descend
                vel_sp = np.array([0.0, 0.0, -0.7 if pos[2] > 1.0 else -0.4])
            thrust, torque = self.ctrl.thrust_and_torque(rot, lin, omega_b, vel_sp, self._yaw_enu, h)
            f = self._alloc_inv @ np.array([thrust, *torque])
            w_cmd = np.sqrt(np.clip(f, 0.0, None) / self.af.kf)
        elif self._s.armed:
            w_cmd = np.full(4, 0.15 * self.af.max_omega)  # idle spin on the ground
        else:
            w_cmd = np.zeros(4)
        w_cmd = np.clip(w_cmd, 0.0, self.af.max_omega)
        self.omega += (w_cmd - self.omega) * min(1.0, h / self.af.motor_tau)
        thrusts = self.af.kf * self.omega**2
        self.motor_thrusts = thrusts
        for r, f in zip(self.rotors, thrusts, strict=True):
            p.applyExternalForce(self.body, -1, [0, 0, float(f)], r.tolist(), p.LINK_FRAME, physicsClientId=self.cid)
        yaw_torque = float(np.sum(self.spin * self.af.km * self.omega**2))
        world_torque = rot @ np.array([0.0, 0.0, yaw_torque])
        p.applyExternalTorque(self.body, -1, world_torque.tolist(), p.WORLD_FRAME, physicsClientId=self.cid)
        drag = -self.af.drag * lin
        p.applyExternalForce(self.body, -1, drag.tolist(), pos.tolist(), p.WORLD_FRAME, physicsClientId=self.cid)
        p.stepSimulation(physicsClientId=self.cid)
        self.time += h
        if self._mode == "land" and self._s.armed:
            if pos[2] < self.af.size[2] / 2 + 0.03 and abs(lin[2]) < 0.2:
                self.disarm(force=True)

    def _update_state(self) -> None:
        pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.cid)
        rot = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        s = self._s
        s.time_s = self.time
        ground_z = self.af.size[2] / 2
        s.position_ned = enu_to_ned(np.array(pos) - np.array([0, 0, ground_z]))
        s.velocity_ned = enu_to_ned(np.array(lin))
        s.attitude_rpy = rpy_flu_to_frd(np.array(p.getEulerFromQuaternion(quat)))
        wb = rot.T @ np.array(ang)
        s.body_rates = np.array([wb[0], -wb[1], -wb[2]])
        s.landed = pos[2] < ground_z + 0.05 and abs(lin[2]) < 0.3
        s.battery_remaining = max(0.0, s.battery_remaining - 0.0)
        s.battery_voltage = 14.0 + 2.8 * s.battery_remaining

    @property
    def enu_position(self) -> np.ndarray:
        return np.array(p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)[0])
