"""Our PyBullet quadrotor with its rotors driven by an autopilot's motor commands.

`PyBulletQuadrotor` flies itself (its cascaded controller turns setpoints into rotor speeds).
A real autopilot (ArduPilot, PX4) brings its own controller and only needs a body: it sends one
command per motor and reads back what its IMU, GPS and barometer would see. `MotorQuadrotor`
is that body: the same airframe, rotor layout, motor lag, drag and PyBullet world, with
  - per-motor throttle 0..1 in, in the autopilots' quad-X order, which is our rotor order:
    1 front-right CCW, 2 back-left CCW, 3 front-left CW, 4 back-right CW (ArduPilot's
    AP_MotorsMatrix quad X; PX4's iris CA_ROTOR0..3 with KM +, +, -, -);
  - a thrust curve thrust = T_max ((1 - e) u + e u^2) (ArduPilot's MOT_THST_EXPO form, e = 0.65
    by default: it linearises this exactly), so the default airframe hovers at u = 0.41;
  - an IMU out: body-frame (FRD) gyro and specific force (what an accelerometer reads: -9.81 z
    at rest on the ground, the ground's reaction included, because it is taken from the body's
    change of velocity over each step less gravity).
The physics rate follows the caller's step (ArduPilot steps 1/400 s per servo frame, PX4's
HIL_SENSOR 1/250 s): each step is split into substeps of at most 1/max_physics_hz.

The self-flying modes are untouched: this is a subclass, and the parent's flights stay exact.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as p

from .quadrotor import Airframe, PyBulletQuadrotor

GRAVITY = 9.81
#: quad-X spin directions per rotor in our (= the autopilots') order, +1 counter-clockwise seen
#: from above. A CCW propeller turns the body clockwise seen from above (a -z torque in FLU).
SPIN_CCW = (1.0, 1.0, -1.0, -1.0)
# ENU world -> NED, FRD body -> FLU: R_ned_frd = _T @ R_enu_flu @ _S
_T = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_S = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class MotorModel:
    thrust_expo: float = 0.65  # 0: thrust linear in throttle, 1: quadratic (thrust ~ speed^2)
    max_physics_hz: float = 400.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.thrust_expo <= 1.0:
            raise ValueError(f"thrust_expo must be in 0..1 (got {self.thrust_expo})")
        if not self.max_physics_hz >= 50.0:
            raise ValueError(f"max_physics_hz must be >= 50 (got {self.max_physics_hz})")


@dataclass(frozen=True)
class Imu:
    """What the autopilot's IMU reads, body FRD."""

    gyro: tuple[float, float, float]  # rad/s
    accel: tuple[float, float, float]  # specific force, m/s^2


def hover_throttle(airframe: Airframe, motors: MotorModel) -> float:
    """The throttle (0..1) at which four rotors carry the airframe's weight."""
    t_max = airframe.kf * airframe.max_omega**2
    frac = airframe.mass * GRAVITY / (4 * t_max)
    e = motors.thrust_expo
    if e == 0:
        return frac
    return (-(1 - e) + math.sqrt((1 - e) ** 2 + 4 * e * frac)) / (2 * e)


class MotorQuadrotor(PyBulletQuadrotor):
    """Build, then per frame: `set_throttle(u)`, `step(dt)`, read `imu`, `state`, `attitude_dcm`."""

    def __init__(self, airframe: Airframe | None = None, motors: MotorModel | None = None,
                 start_ned: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0),
                 client: int | None = None) -> None:
        super().__init__(airframe, None, start_ned, client)
        self.motors = motors or MotorModel()
        self._mode = "motors"
        self._throttle = (0.0, 0.0, 0.0, 0.0)
        self._h_set = 1.0 / 240.0
        af = self.af
        # per rotor: roll and pitch torque per N of thrust (FLU: y F, -x F) and yaw per N
        self._motor_coefs = tuple((float(r[1]), -float(r[0]), -sp * af.km / af.kf)
                                  for r, sp in zip(self.rotors, SPIN_CCW, strict=True))
        self._imu = Imu((0.0, 0.0, 0.0), (0.0, 0.0, -GRAVITY))

    # -- the autopilot's side ------------------------------------------------------------
    def set_throttle(self, throttle: Sequence[float]) -> None:
        """Four motor commands 0..1 (clipped; NaN reads 0), autopilot motor order 1..4."""
        if len(throttle) != 4:
            raise ValueError(f"a quadrotor takes 4 motor commands (got {len(throttle)})")
        self._throttle = tuple(min(max(float(u), 0.0), 1.0) if math.isfinite(u) else 0.0 for u in throttle)

    @property
    def imu(self) -> Imu:
        return self._imu

    @property
    def attitude_dcm(self) -> np.ndarray:
        """(3, 3) rotation body FRD -> NED."""
        quat = p.getBasePositionAndOrientation(self.body, self.cid)[1]
        r = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        return _T @ r @ _S

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """(w, x, y, z) of body FRD -> NED (ArduPilot's q1..q4, PX4's / MAVLink's order)."""
        return dcm_to_quaternion(self.attitude_dcm)

    # -- FlightModel: the autopilot flies, not us ----------------------------------------
    def arm(self) -> bool:
        self._s.armed = True
        return True

    def disarm(self, force: bool = False) -> bool:
        self._s.armed = False
        return True

    def set_position_target(self, position_ned, yaw=None, speed=None) -> None:
        raise NotImplementedError("a motor-driven body has no position controller: the autopilot flies it")

    def set_velocity_target(self, velocity_ned, yaw_rate: float = 0.0) -> None:
        raise NotImplementedError("a motor-driven body has no velocity controller: the autopilot flies it")

    def land(self) -> None:
        raise NotImplementedError("a motor-driven body cannot land itself: the autopilot flies it")

    def step(self, dt: float) -> None:
        if not dt > 0:
            raise ValueError(f"step needs dt > 0 (got {dt})")
        n = max(1, math.ceil(dt * self.motors.max_physics_hz - 1e-9))
        h = dt / n
        if h != self._h_set:
            p.setTimeStep(h, physicsClientId=self.cid)
            self._h_set = h
            self._lag = min(1.0, h / self.af.motor_tau)
        v0 = p.getBaseVelocity(self.body, self.cid)[0]
        for _ in range(n):
            self._motor_substep(h)
        self._update_state()
        pos, lin, ang, rot = self._last_read
        # specific force: the change of velocity over the step less gravity, into body FRD
        fx, fy, fz = (lin[0] - v0[0]) / dt, (lin[1] - v0[1]) / dt, (lin[2] - v0[2]) / dt + GRAVITY
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
        bx = r00 * fx + r10 * fy + r20 * fz
        by = r01 * fx + r11 * fy + r21 * fz
        bz = r02 * fx + r12 * fy + r22 * fz
        self._imu = Imu(tuple(float(x) for x in self._s.body_rates), (bx, -by, -bz))

    def _motor_substep(self, h: float) -> None:
        cid, body = self.cid, self.body
        pos, quat = p.getBasePositionAndOrientation(body, cid)
        lin, _ = p.getBaseVelocity(body, cid)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = p.getMatrixFromQuaternion(quat)
        e, wmax = self.motors.thrust_expo, self.af.max_omega
        k = self._lag
        omega = []
        for w, u in zip(self.omega, self._throttle, strict=True):
            cmd = wmax * math.sqrt((1 - e) * u + e * u * u)  # thrust kf w^2 on the curve
            omega.append(w + (cmd - w) * k)
        self.omega = omega
        kf, drag = self.af.kf, self.af.drag
        thrusts = [kf * w * w for w in omega]
        total = sum(thrusts)
        bx = by = bz = 0.0
        for f, (cx, cy, cz) in zip(thrusts, self._motor_coefs, strict=True):
            bx += cx * f
            by += cy * f
            bz += cz * f
        force = (total * r02 - drag * lin[0], total * r12 - drag * lin[1], total * r22 - drag * lin[2])
        torque = (r00 * bx + r01 * by + r02 * bz, r10 * bx + r11 * by + r12 * bz, r20 * bx + r21 * by + r22 * bz)
        p.applyExternalForce(body, -1, force, pos, p.WORLD_FRAME, cid)
        p.applyExternalTorque(body, -1, torque, p.WORLD_FRAME, cid)
        p.stepSimulation(cid)
        self.time += h


def dcm_to_quaternion(r: np.ndarray) -> tuple[float, float, float, float]:
    """(w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method: stable for any angle)."""
    tr = float(r[0, 0] + r[1, 1] + r[2, 2])
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s)
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2
        q = ((r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s)
    elif r[1, 1] > r[2, 2]:
        s = math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2
        q = ((r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s)
    else:
        s = math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2
        q = ((r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s)
    sign = -1.0 if q[0] < 0 else 1.0
    return tuple(float(sign * x) for x in q)  # type: ignore[return-value]
