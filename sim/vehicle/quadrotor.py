"""A quadrotor rigid body in PyBullet (headless DIRECT), flown by the cascaded controller.

Four rotors in X configuration each apply a thrust kf * w^2 at their arm's tip and a drag
torque km * w^2 about the body z axis (alternating directions); motor speeds follow their
commands with a first-order lag; the body feels gravity and linear air drag. 240 Hz physics,
the controller at the same rate. Implements the FlightModel contract (sim/vehicle/model.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p

from .controller import CascadedController, Gains
from .frames import enu_yaw_to_ned, ned_to_enu, ned_yaw_to_enu
from .model import VehicleState

PHYSICS_HZ = 240
_WORLD_FRAME = p.WORLD_FRAME


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
        # physics only: cameras see the field's grass (field.py), which lies over this plane;
        # an invisible plane halves the software renderer's time and leaves images unchanged
        p.changeVisualShape(self.ground, -1, rgbaColor=[1, 1, 1, 0], physicsClientId=self.cid)
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
        rotors = np.array([[d, -d, 0], [-d, d, 0], [d, d, 0], [-d, -d, 0]], dtype=float)
        spin = np.array([1, 1, -1, -1], dtype=float)
        self.rotors = tuple(tuple(float(x) for x in r) for r in rotors)
        self.spin = tuple(float(x) for x in spin)
        alloc = np.vstack([
            np.ones(4),
            rotors[:, 1],  # roll torque = y * F
            -rotors[:, 0],  # pitch torque = -x * F
            spin * self.af.km / self.af.kf,
        ])
        self.alloc_inv = np.linalg.inv(alloc)
        # per rotor: kf y, -kf x (roll and pitch torque per (rad/s)^2) and spin km (yaw)
        self._rotor_coefs = tuple((self.af.kf * float(r[1]), -self.af.kf * float(r[0]), sp * self.af.km)
                                  for r, sp in zip(rotors, spin, strict=True))
        self._alloc_rows = tuple(tuple(float(x) for x in row) for row in self.alloc_inv)
        # flat tuples and plain floats for the substep (one unpack, no attribute lookups)
        self._alloc_flat = tuple(x for row in self._alloc_rows for x in row)
        self._coefs_flat = tuple(x for c in self._rotor_coefs for x in c)
        self._consts = (1.0 / self.af.kf, self.af.max_omega, self.af.max_omega * self.af.max_omega, self.af.kf,
                        self.af.drag)
        self._h = 1.0 / PHYSICS_HZ
        self._lag = min(1.0, self._h / self.af.motor_tau)
        self._idle_cmd = [0.15 * self.af.max_omega] * 4
        self._stop_cmd = [0.0] * 4
        self.omega = [0.0] * 4  # rotor speeds, rad/s
        self._s = VehicleState()
        self._mode = "idle"  # idle | position | velocity | land
        self._target_enu = tuple(float(x) for x in start)
        self._vel_enu = (0.0, 0.0, 0.0)
        self._speed: float | None = None
        self._yaw_enu = np.pi / 2  # facing north
        self.time = 0.0
        self._last_read: tuple | None = None  # (pos, lin, ang, rot) as _update_state read them
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
        self._target_enu = tuple(pos)
        self._mode = "idle"
        return True

    def disarm(self, force: bool = False) -> bool:
        if not self._s.landed and not force:
            return False
        self._s.armed = False
        self._mode = "idle"
        self.omega = [0.0] * 4
        return True

    def set_position_target(self, position_ned, yaw=None, speed=None) -> None:
        self._target_enu = tuple(float(x) for x in ned_to_enu(np.asarray(position_ned, dtype=float)))
        if yaw is not None and np.isfinite(yaw):
            self._yaw_enu = ned_yaw_to_enu(float(yaw))
        self._speed = speed
        self._mode = "position"

    def set_velocity_target(self, velocity_ned, yaw_rate: float = 0.0) -> None:
        self._vel_enu = tuple(float(x) for x in ned_to_enu(np.asarray(velocity_ned, dtype=float)))
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
        """One 240 Hz step in plain floats: per-call numpy overhead on 3-vectors cost ten times
        the physics (docs/vehicle.md). The four rotor forces and the drag are summed into one
        force at the centre of mass and one torque, as Bullet itself sums them."""
        h = self._h
        cid, body = self.cid, self.body
        # the world as the last _update_state read it (only stepSimulation moves it): the first
        # substep of a step reads nothing; the others read (positional client ids: keyword
        # parsing costs as much as a getter)
        read, self._last_read = self._last_read, None
        if read is not None:
            pos, lin, ang, rot = read
        else:
            pos, quat = p.getBasePositionAndOrientation(body, cid)
            lin, ang = p.getBaseVelocity(body, cid)
            rot = p.getMatrixFromQuaternion(quat)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
        ikf, wmax, wmax2, kf, drag = self._consts
        s = self._s
        w0, w1, w2, w3 = self.omega
        if s.armed and self._mode != "idle":
            wb = (r00 * ang[0] + r10 * ang[1] + r20 * ang[2], r01 * ang[0] + r11 * ang[1] + r21 * ang[2],
                  r02 * ang[0] + r12 * ang[1] + r22 * ang[2])
            if self._mode == "position":
                vel_sp = self.ctrl.velocity_setpoint(pos, self._target_enu, self._speed)
            elif self._mode == "velocity":
                vel_sp = self._vel_enu
            else:  # land: hold horizontal position, descend
                vel_sp = (0.0, 0.0, -0.7 if pos[2] > 1.0 else -0.4)
            thrust, (tx, ty, tz) = self.ctrl.thrust_and_torque(rot, lin, wb, vel_sp, self._yaw_enu, h)
            # mixer: rotor thrusts from the inverse allocation, speeds from thrust = kf w^2
            a00, a01, a02, a03, a10, a11, a12, a13, a20, a21, a22, a23, a30, a31, a32, a33 = self._alloc_flat
            sqrt = math.sqrt
            f = a00 * thrust + a01 * tx + a02 * ty + a03 * tz
            fi = f * ikf
            c0 = (sqrt(fi) if fi < wmax2 else wmax) if f > 0.0 else 0.0
            f = a10 * thrust + a11 * tx + a12 * ty + a13 * tz
            fi = f * ikf
            c1 = (sqrt(fi) if fi < wmax2 else wmax) if f > 0.0 else 0.0
            f = a20 * thrust + a21 * tx + a22 * ty + a23 * tz
            fi = f * ikf
            c2 = (sqrt(fi) if fi < wmax2 else wmax) if f > 0.0 else 0.0
            f = a30 * thrust + a31 * tx + a32 * ty + a33 * tz
            fi = f * ikf
            c3 = (sqrt(fi) if fi < wmax2 else wmax) if f > 0.0 else 0.0
        elif s.armed:
            c0 = c1 = c2 = c3 = self._idle_cmd[0]  # idle spin on the ground
        else:
            c0 = c1 = c2 = c3 = 0.0
        k = self._lag
        w0, w1, w2, w3 = w0 + (c0 - w0) * k, w1 + (c1 - w1) * k, w2 + (c2 - w2) * k, w3 + (c3 - w3) * k
        self.omega = [w0, w1, w2, w3]
        q0, q1, q2, q3 = w0 * w0, w1 * w1, w2 * w2, w3 * w3
        # rotor i pushes kf q_i along body z at (x_i, y_i): torque (y_i, -x_i, 0) kf q_i; its drag
        # turns the body by spin_i km q_i
        a0, b0, s0, a1, b1, s1, a2, b2, s2, a3, b3, s3 = self._coefs_flat
        total = kf * (q0 + q1 + q2 + q3)
        bx = a0 * q0 + a1 * q1 + a2 * q2 + a3 * q3
        by = b0 * q0 + b1 * q1 + b2 * q2 + b3 * q3
        bz = s0 * q0 + s1 * q1 + s2 * q2 + s3 * q3
        force = (total * r02 - drag * lin[0], total * r12 - drag * lin[1], total * r22 - drag * lin[2])
        torque = (r00 * bx + r01 * by + r02 * bz, r10 * bx + r11 * by + r12 * bz, r20 * bx + r21 * by + r22 * bz)
        p.applyExternalForce(body, -1, force, pos, _WORLD_FRAME, cid)
        p.applyExternalTorque(body, -1, torque, _WORLD_FRAME, cid)
        p.stepSimulation(cid)
        self.time += h
        if self._mode == "land" and s.armed:
            if pos[2] < self.af.size[2] / 2 + 0.03 and abs(lin[2]) < 0.2:
                self.disarm(force=True)

    def _update_state(self) -> None:
        pos, quat = p.getBasePositionAndOrientation(self.body, self.cid)
        lin, ang = p.getBaseVelocity(self.body, self.cid)
        rot = p.getMatrixFromQuaternion(quat)
        self._last_read = (pos, lin, ang, rot)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
        roll, pitch, yaw = p.getEulerFromQuaternion(quat)
        s = self._s
        s.time_s = self.time
        ground_z = self.af.size[2] / 2
        s.position_ned = np.array([pos[1], pos[0], -(pos[2] - ground_z)])
        s.velocity_ned = np.array([lin[1], lin[0], -lin[2]])
        s.attitude_rpy = np.array([roll, -pitch, enu_yaw_to_ned(yaw)])
        wx = r00 * ang[0] + r10 * ang[1] + r20 * ang[2]
        wy = r01 * ang[0] + r11 * ang[1] + r21 * ang[2]
        wz = r02 * ang[0] + r12 * ang[1] + r22 * ang[2]
        s.body_rates = np.array([wx, -wy, -wz])  # FLU -> FRD
        s.landed = pos[2] < ground_z + 0.05 and abs(lin[2]) < 0.3
        s.battery_voltage = 14.0 + 2.8 * s.battery_remaining

    @property
    def motor_thrusts(self) -> np.ndarray:
        """(4,) rotor thrusts now, N."""
        return self.af.kf * np.square(self.omega)

    @property
    def enu_position(self) -> np.ndarray:
        return np.array(p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)[0])
