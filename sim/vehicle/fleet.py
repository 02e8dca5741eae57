"""Many vehicles stepped together in one process: the physics and the controller run with
numpy over the vehicle axis, one `step` for the whole fleet (issue 13).

- `QuadrotorFleet`: N quadrotor bodies in one PyBullet world (one stepSimulation for all),
  flown by `BatchController`; the same airframe, maths and rates as PyBulletQuadrotor, and the
  same trajectories (tests/sim/vehicle/test_fleet.py). Vehicles never touch each other: each
  body collides with the ground only, and each sits at its own offset in the world, so its
  local NED frame is the one a lone quadrotor would have.
- `KinematicFleet`: N kinematic point masses (kinematic.py's model), vectorised.

Each fleet hands out `members`, one FlightModel per vehicle, for the MAVLink endpoints. The
fleet steps its members; a member's own `step` refuses, so no vehicle is stepped twice.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pybullet as p

from .controller import BatchController, Gains
from .frames import enu_yaw_to_ned, ned_yaw_to_enu
from .model import VehicleState
from .quadrotor import _WORLD_FRAME, PHYSICS_HZ, Airframe

IDLE, POSITION, VELOCITY, LAND = 0, 1, 2, 3
#: metres between vehicles' origins in the shared world (they never interact anyway)
SPACING_M = 20.0


def _ned_to_enu(v: Sequence[float]) -> np.ndarray:
    return np.array([float(v[1]), float(v[0]), -float(v[2])])


class FleetMember:
    """One vehicle of a fleet, seen through the FlightModel contract."""

    def __init__(self, fleet: QuadrotorFleet | KinematicFleet, index: int) -> None:
        self.fleet, self.i = fleet, index

    @property
    def state(self) -> VehicleState:
        return self.fleet.states[self.i]

    def arm(self) -> bool:
        return self.fleet.arm(self.i)

    def disarm(self, force: bool = False) -> bool:
        return self.fleet.disarm(self.i, force)

    def set_position_target(self, position_ned, yaw=None, speed=None) -> None:
        self.fleet.set_position_target(self.i, position_ned, yaw, speed)

    def set_velocity_target(self, velocity_ned, yaw_rate: float = 0.0) -> None:
        self.fleet.set_velocity_target(self.i, velocity_ned)

    def land(self) -> None:
        self.fleet.land(self.i)

    def step(self, dt: float) -> None:
        raise RuntimeError("a fleet member is stepped by its fleet: call fleet.step(dt) once for all vehicles")

    def close(self) -> None:
        """The fleet owns the world; closing one member leaves the others flying."""


class QuadrotorFleet:
    def __init__(self, n: int, airframe: Airframe | None = None, gains: Gains | None = None) -> None:
        if n < 1:
            raise ValueError(f"a fleet needs at least one vehicle (got {n})")
        self.n, self.af = n, airframe or Airframe()
        af = self.af
        self.cid = p.connect(p.DIRECT)
        p.setGravity(0, 0, -9.81, physicsClientId=self.cid)
        p.setTimeStep(1.0 / PHYSICS_HZ, physicsClientId=self.cid)
        ground = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=self.cid)
        self.ground = p.createMultiBody(0, ground, physicsClientId=self.cid)
        # the ground in group 1 meets everything; vehicles (group 2) meet group 1 only, so they
        # pass through each other
        p.setCollisionFilterGroupMask(self.ground, -1, 1, 0xFFFF, physicsClientId=self.cid)
        half = [s / 2 for s in af.size]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=self.cid)
        side = math.ceil(math.sqrt(n))
        self.offset = np.array([[SPACING_M * (i % side), SPACING_M * (i // side), 0.0] for i in range(n)])
        north = p.getQuaternionFromEuler([0, 0, np.pi / 2])
        self.bodies = []
        for i in range(n):
            start = self.offset[i] + [0.0, 0.0, half[2]]
            b = p.createMultiBody(af.mass, col, -1, start.tolist(), north, physicsClientId=self.cid)
            p.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=self.cid)
            p.setCollisionFilterGroupMask(b, -1, 2, 1, physicsClientId=self.cid)
            self.bodies.append(b)
        m, (a, bb, c) = af.mass, af.size
        self.J = np.diag([m * (bb * bb + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + bb * bb) / 12])
        self.ctrl = BatchController(n, af.mass, self.J, gains)
        d = af.arm / np.sqrt(2)
        rotors = np.array([[d, -d, 0], [-d, d, 0], [d, d, 0], [-d, -d, 0]], dtype=float)
        spin = np.array([1, 1, -1, -1], dtype=float)
        alloc = np.vstack([np.ones(4), rotors[:, 1], -rotors[:, 0], spin * af.km / af.kf])
        self._alloc_inv_t = np.linalg.inv(alloc).T
        # (4, 3): per rotor, body torque per (rad/s)^2 (roll y kf, pitch -x kf, yaw spin km)
        self._rotor_torque = np.stack([af.kf * rotors[:, 1], -af.kf * rotors[:, 0], spin * af.km], axis=1)
        self.omega = np.zeros((n, 4))
        self.armed = np.zeros(n, dtype=bool)
        self.mode = np.zeros(n, dtype=np.int64)
        self.target = self.offset + [0.0, 0.0, half[2]]
        self.vel_cmd = np.zeros((n, 3))
        self.speed = np.full(n, np.nan)
        self.yaw = np.full(n, np.pi / 2)
        self.time = 0.0
        self.states = [VehicleState() for _ in range(n)]
        self.members = [FleetMember(self, i) for i in range(n)]
        self._update_states()

    # -- commands (FleetMember forwards here) ----------------------------------------------
    def arm(self, i: int) -> bool:
        s = self.states[i]
        if s.armed:
            return True
        if not s.landed:
            return False
        s.armed = self.armed[i] = True
        self.ctrl.reset(i)
        pos, _ = p.getBasePositionAndOrientation(self.bodies[i], self.cid)
        self.target[i] = pos
        self.mode[i] = IDLE
        return True

    def disarm(self, i: int, force: bool = False) -> bool:
        s = self.states[i]
        if not s.landed and not force:
            return False
        s.armed = self.armed[i] = False
        self.mode[i] = IDLE
        self.omega[i] = 0.0
        return True

    def set_position_target(self, i: int, position_ned, yaw=None, speed=None) -> None:
        self.target[i] = _ned_to_enu(position_ned) + self.offset[i]
        if yaw is not None and np.isfinite(yaw):
            self.yaw[i] = ned_yaw_to_enu(float(yaw))
        self.speed[i] = np.nan if speed is None else float(speed)
        self.mode[i] = POSITION

    def set_velocity_target(self, i: int, velocity_ned) -> None:
        self.vel_cmd[i] = _ned_to_enu(velocity_ned)
        self.mode[i] = VELOCITY

    def land(self, i: int) -> None:
        self.mode[i] = LAND

    # -- physics -----------------------------------------------------------------------------
    def step(self, dt: float) -> None:
        for _ in range(max(1, int(round(dt * PHYSICS_HZ)))):
            self._substep()
        self._update_states()

    def _read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        cid = self.cid
        poses = [p.getBasePositionAndOrientation(b, cid) for b in self.bodies]
        vels = [p.getBaseVelocity(b, cid) for b in self.bodies]
        pos = np.array([x[0] for x in poses])
        quat = np.array([x[1] for x in poses])
        lin = np.array([v[0] for v in vels])
        ang = np.array([v[1] for v in vels])
        return pos, quat, lin, ang

    def _substep(self) -> None:
        h, af = 1.0 / PHYSICS_HZ, self.af
        pos, quat, lin, ang = self._read()
        rot = _quat_to_rot(quat)
        flying = self.armed & (self.mode != IDLE)
        w_cmd = np.where(self.armed, 0.15 * af.max_omega, 0.0)[:, None] * np.ones(4)
        if flying.any():
            wb = np.einsum("nki,nk->ni", rot, ang)
            vel_sp = self.ctrl.velocity_setpoint(pos, self.target, self.speed)
            land_sp = np.where(pos[:, 2] > 1.0, -0.7, -0.4)
            vel_sp = np.where((self.mode == VELOCITY)[:, None], self.vel_cmd, vel_sp)
            is_land = self.mode == LAND
            vel_sp[is_land] = 0.0
            vel_sp[is_land, 2] = land_sp[is_land]
            held = self.ctrl.vel_int.copy()
            thrust, torque = self.ctrl.thrust_and_torque(rot, lin, wb, vel_sp, self.yaw, h)
            self.ctrl.vel_int[~flying] = held[~flying]  # only flying vehicles integrate
            f = np.concatenate([thrust[:, None], torque], axis=1) @ self._alloc_inv_t
            w_fly = np.sqrt(np.clip(f, 0.0, None) / af.kf)
            w_cmd = np.where(flying[:, None], w_fly, w_cmd)
        np.clip(w_cmd, 0.0, af.max_omega, out=w_cmd)
        self.omega += (w_cmd - self.omega) * min(1.0, h / af.motor_tau)
        q = self.omega * self.omega
        total = af.kf * q.sum(axis=1)
        body_torque = q @ self._rotor_torque
        force = total[:, None] * rot[:, :, 2] - af.drag * lin
        torque = np.einsum("nij,nj->ni", rot, body_torque)
        cid = self.cid
        for b, fo, to, po in zip(self.bodies, force.tolist(), torque.tolist(), pos.tolist(), strict=True):
            p.applyExternalForce(b, -1, fo, po, _WORLD_FRAME, cid)
            p.applyExternalTorque(b, -1, to, _WORLD_FRAME, cid)
        p.stepSimulation(cid)
        self.time += h
        touch = (self.mode == LAND) & self.armed & (pos[:, 2] < af.size[2] / 2 + 0.03) & (np.abs(lin[:, 2]) < 0.2)
        for i in np.flatnonzero(touch):
            self.disarm(int(i), force=True)

    def _update_states(self) -> None:
        pos, quat, lin, ang = self._read()
        rot = _quat_to_rot(quat)
        wb = np.einsum("nki,nk->ni", rot, ang)
        ground_z = self.af.size[2] / 2
        local = pos - self.offset
        for i, s in enumerate(self.states):
            roll, pitch, yaw = p.getEulerFromQuaternion(quat[i].tolist())
            s.time_s = self.time
            s.position_ned = np.array([local[i, 1], local[i, 0], -(local[i, 2] - ground_z)])
            s.velocity_ned = np.array([lin[i, 1], lin[i, 0], -lin[i, 2]])
            s.attitude_rpy = np.array([roll, -pitch, enu_yaw_to_ned(yaw)])
            s.body_rates = np.array([wb[i, 0], -wb[i, 1], -wb[i, 2]])
            s.landed = bool(pos[i, 2] < ground_z + 0.05 and abs(lin[i, 2]) < 0.3)
            s.battery_voltage = 14.0 + 2.8 * s.battery_remaining

    @property
    def motor_thrusts(self) -> np.ndarray:
        """(N, 4) rotor thrusts now, N."""
        return self.af.kf * self.omega**2

    def close(self) -> None:
        if p.isConnected(self.cid):
            p.disconnect(self.cid)


def _quat_to_rot(q: np.ndarray) -> np.ndarray:
    """(N, 4) PyBullet quaternions (x, y, z, w) -> (N, 3, 3) body-to-world rotations."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    xx, yy, zz, xy, xz, yz, wx, wy, wz = x * x, y * y, z * z, x * y, x * z, y * z, w * x, w * y, w * z
    return np.stack([
        1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy),
        2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx),
        2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy),
    ], axis=1).reshape(-1, 3, 3)


class KinematicFleet:
    """kinematic.py's point mass for N vehicles at once: the same limits and the same steps."""

    def __init__(self, n: int, max_speed: float = 5.0, max_climb: float = 2.0, max_accel: float = 4.0,
                 position_gain: float = 1.2) -> None:
        if n < 1:
            raise ValueError(f"a fleet needs at least one vehicle (got {n})")
        self.n = n
        self.max_speed, self.max_climb, self.max_accel, self.kp = max_speed, max_climb, max_accel, position_gain
        self.pos = np.zeros((n, 3))
        self.vel = np.zeros((n, 3))
        self.armed = np.zeros(n, dtype=bool)
        self.mode = np.zeros(n, dtype=np.int64)  # IDLE: hover in place (no target)
        self.target = np.zeros((n, 3))
        self.vel_cmd = np.zeros((n, 3))
        self.speed = np.full(n, np.nan)
        self.yaw = np.full(n, np.nan)
        self.time = 0.0
        self.states = [VehicleState() for _ in range(n)]
        self.members = [FleetMember(self, i) for i in range(n)]

    def arm(self, i: int) -> bool:
        if not self.armed[i]:
            self.armed[i] = self.states[i].armed = True
            self.target[i] = self.pos[i]
            self.mode[i] = POSITION
        return True

    def disarm(self, i: int, force: bool = False) -> bool:
        if not self.states[i].landed and not force:
            return False
        self.armed[i] = self.states[i].armed = False
        self.mode[i] = IDLE
        return True

    def set_position_target(self, i: int, position_ned, yaw=None, speed=None) -> None:
        self.target[i] = np.asarray(position_ned, dtype=float)
        self.speed[i] = np.nan if speed is None else float(speed)
        self.yaw[i] = np.nan if yaw is None else float(yaw)
        self.mode[i] = POSITION

    def set_velocity_target(self, i: int, velocity_ned) -> None:
        self.vel_cmd[i] = np.asarray(velocity_ned, dtype=float)
        self.mode[i] = VELOCITY

    def land(self, i: int) -> None:
        self.mode[i] = LAND

    def step(self, dt: float) -> None:
        self.time += dt
        want = np.zeros((self.n, 3))
        want = np.where((self.mode == POSITION)[:, None], self.kp * (self.target - self.pos), want)
        want = np.where((self.mode == VELOCITY)[:, None], self.vel_cmd, want)
        want[self.mode == LAND] = [0.0, 0.0, 0.7]
        horiz = np.hypot(want[:, 0], want[:, 1])
        ok = np.isfinite(self.speed) & (self.speed > 0)
        vmax = np.where(ok, np.minimum(self.max_speed, np.where(ok, self.speed, 0.0)), self.max_speed)
        want[:, :2] *= np.where(horiz > vmax, vmax / np.maximum(horiz, 1e-300), 1.0)[:, None]
        np.clip(want[:, 2], -self.max_climb, self.max_climb, out=want[:, 2])
        dv = want - self.vel
        lim = self.max_accel * dt
        nrm = np.linalg.norm(dv, axis=1)
        dv *= np.where(nrm > lim, lim / np.maximum(nrm, 1e-300), 1.0)[:, None]
        a = self.armed
        self.vel[a] += dv[a]
        self.vel[~a] = 0.0
        self.pos[a] += self.vel[a] * dt
        down = a & (self.pos[:, 2] >= 0.0)
        self.pos[down, 2] = 0.0
        self.vel[down, 2] = np.minimum(self.vel[down, 2], 0.0)
        landed = np.where(a, down, np.array([s.landed for s in self.states]))
        for i in np.flatnonzero(down & (self.mode == LAND)):
            self.armed[i] = False
            self.mode[i] = IDLE
        for i, s in enumerate(self.states):
            s.time_s = self.time
            s.position_ned = self.pos[i].copy()
            s.velocity_ned = self.vel[i].copy()
            s.landed = bool(landed[i])
            s.armed = bool(self.armed[i])
            if a[i]:
                if np.isfinite(self.yaw[i]):
                    s.attitude_rpy[2] = self.yaw[i]
                s.battery_remaining = max(0.0, s.battery_remaining - dt / 1800.0)
                s.battery_voltage = 14.0 + 2.8 * s.battery_remaining

    def close(self) -> None:
        pass
