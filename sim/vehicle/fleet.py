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
from .frames import ned_yaw_to_enu
from .free_flight import FreeFlight
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
    """N quadrotors in one PyBullet world. In the air (above `FREE_ABOVE_M`) a vehicle's body
    is stepped by `free_flight.FreeFlight`, Bullet's own free-body step in numpy over the
    fleet (the same bits: test_free_flight.py), so a fleet in the air makes no PyBullet call;
    near the ground (below `BULLET_BELOW_M`) PyBullet steps it, for the ground contact.
    `free_flight=False` steps every body in PyBullet always (the reference the tests fly). The
    numpy step costs about the same whatever the number of vehicles it steps, so vehicles fly
    free only when enough of them are in the air (`free_flight_min`)."""

    #: a vehicle in PyBullet goes to the numpy step above this height (m, world z of its centre)
    FREE_ABOVE_M = 1.0
    #: ... and back to PyBullet below this one: far above any contact (the body's half diagonal
    #: is 0.25 m, Bullet's contact distances centimetres; at the 100 m/s velocity clamp a step is 0.42 m)
    BULLET_BELOW_M = 0.75

    def __init__(self, n: int, airframe: Airframe | None = None, gains: Gains | None = None,
                 free_flight: bool = True, free_flight_min: int | None = None) -> None:
        """free_flight_min: fly free only when at least this many vehicles are in the air (None:
        where the numpy step pays for itself)."""
        if n < 1:
            raise ValueError(f"a fleet needs at least one vehicle (got {n})")
        self.n, self.af = n, airframe or Airframe()
        af = self.af
        self.cid = p.connect(p.DIRECT)
        gravity = (0.0, 0.0, -9.81)
        p.setGravity(*gravity, physicsClientId=self.cid)
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
        self._col = col
        #: each vehicle's PyBullet body; None while it flies free (numpy step): a body left in the
        #: world would still cost PyBullet its integration and broadphase every step
        self.bodies: list[int | None] = [self._body(self.offset[i] + [0.0, 0.0, half[2]], north) for i in range(n)]
        m, (a, bb, c) = af.mass, af.size
        self.J = np.diag([m * (bb * bb + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + bb * bb) / 12])
        self.ctrl = BatchController(n, af.mass, self.J, gains)
        d = af.arm / np.sqrt(2)
        rotors = np.array([[d, -d, 0], [-d, d, 0], [d, d, 0], [-d, -d, 0]], dtype=float)
        spin = np.array([1, 1, -1, -1], dtype=float)
        alloc = np.vstack([np.ones(4), rotors[:, 1], -rotors[:, 0], spin * af.km / af.kf])
        self._alloc_inv = np.linalg.inv(alloc)  # rotor thrusts from (thrust, torques)
        # (3, 4): body torque per rotor (rad/s)^2 (roll y kf, pitch -x kf, yaw spin km)
        self._rotor_torque = np.stack([af.kf * rotors[:, 1], -af.kf * rotors[:, 0], spin * af.km])
        self._lag = min(1.0, (1.0 / PHYSICS_HZ) / af.motor_tau)
        # Bullet's own mass and inertia diagonal (from the box shape), for the numpy step
        info = p.getDynamicsInfo(self.bodies[0], -1, physicsClientId=self.cid)
        self._free_flight = FreeFlight(info[0], info[2], gravity, 1.0 / PHYSICS_HZ) if free_flight else None
        # the numpy step costs ~35 + 0.5 N us a substep whatever the number it steps, PyBullet ~3.6 us
        # a vehicle (reads, forces, its share of stepSimulation; timeit on 2-core EPYC): vehicles
        # fly free only when that many are in the air (12 of 16; 24 of 100), with 2 of hysteresis;
        # a fleet of fewer than 12 never does (n + 1 is never reached)
        pays = math.ceil((35.0 + 0.5 * n) / 3.6)
        #: vehicles in the air needed to fly free (may be changed between steps)
        self.free_flight_min = (pays if pays <= n else n + 1) if free_flight_min is None else free_flight_min
        self._om = np.zeros((4, n))  # rotor speeds, rad/s, rotor first
        self.armed = np.zeros(n, dtype=bool)
        self.mode = np.zeros(n, dtype=np.int64)
        self.target = self.offset + [0.0, 0.0, half[2]]
        self._off_ned = np.ascontiguousarray(self.offset.T[[1, 0, 2]])  # offsets in the NED rows' order
        self.vel_cmd = np.zeros((n, 3))
        self.speed = np.full(n, np.nan)
        self.yaw = np.full(n, np.pi / 2)
        self.time = 0.0
        self._masks: tuple | None = None  # _mode_masks
        # the world now, component first (the numpy step's layout): positions (3, N), angular
        # then linear velocities (6, N), Bullet's m_baseQuat of the vehicles in free flight (4, N),
        # the orientations PyBullet reports for the others (N, 4), rotations body to world (9, N:
        # row-major entries)
        self._p, self._wv = np.zeros((3, n)), np.zeros((6, n))
        self._q = np.zeros((4, n))
        self._q[3] = 1.0  # the rows of vehicles in PyBullet are stepped but unused: keep them unit quaternions
        self._quat = np.zeros((n, 4))
        self._r9 = np.zeros((9, n))
        self._m: np.ndarray | None = None  # matrices(self._q) (9, N), when every vehicle is free
        self.free = np.zeros(n, dtype=bool)  # stepped by the numpy step (in the air), not PyBullet
        self._set_split()
        self._read_bullet(np.arange(n))
        # what the states read (QuadState): positions, velocities, attitudes and body rates made
        # fresh every step; the battery as the MAVLink side writes it (VehicleState's defaults)
        self.battery_remaining, self.battery_voltage = np.ones(n), np.full(n, 16.8)
        self.states = [QuadState(self, i) for i in range(n)]
        self.members = [FleetMember(self, i) for i in range(n)]
        self._update_states()

    def _body(self, pos, orn) -> int:
        """A vehicle's body at pos (ENU) and orientation (x, y, z, w), at rest."""
        cid = self.cid
        b = p.createMultiBody(self.af.mass, self._col, -1, list(pos), orn, physicsClientId=cid)
        p.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
        p.setCollisionFilterGroupMask(b, -1, 2, 1, physicsClientId=cid)
        return b

    # -- commands (FleetMember forwards here) ----------------------------------------------
    def arm(self, i: int) -> bool:
        if self.armed[i]:
            return True
        if not self.landed[i]:
            return False
        self.armed[i] = True
        self._masks = None
        self.ctrl.reset(i)
        self.target[i] = self._p[:, i]
        self.mode[i] = IDLE
        return True

    def disarm(self, i: int, force: bool = False) -> bool:
        if not self.landed[i] and not force:
            return False
        self.armed[i] = False
        self._masks = None
        self.mode[i] = IDLE
        self._om[:, i] = 0.0
        return True

    def set_position_target(self, i: int, position_ned, yaw=None, speed=None) -> None:
        self.target[i] = _ned_to_enu(position_ned) + self.offset[i]
        if yaw is not None and np.isfinite(yaw):
            self.yaw[i] = ned_yaw_to_enu(float(yaw))
        self.speed[i] = np.nan if speed is None else float(speed)
        self.mode[i] = POSITION
        self._masks = None

    def set_velocity_target(self, i: int, velocity_ned) -> None:
        self.vel_cmd[i] = _ned_to_enu(velocity_ned)
        self.mode[i] = VELOCITY
        self._masks = None

    def land(self, i: int) -> None:
        self.mode[i] = LAND
        self._masks = None

    # -- physics -----------------------------------------------------------------------------
    def step(self, dt: float) -> None:
        self._masks = None  # the commands may have changed: the mode masks are made again
        for _ in range(max(1, int(round(dt * PHYSICS_HZ)))):
            self._substep()
        self._update_states()

    def _read_bullet(self, rows: np.ndarray) -> None:
        """Read the bodies `rows` from PyBullet into the state arrays (PyBullet answers per
        body). Rotations by getMatrixFromQuaternion (0.2 us a body: cheaper than a numpy pass
        over a few rows; free_flight.matrices makes the same numbers)."""
        cid, flat, bodies, rot = self.cid, [], self.bodies, p.getMatrixFromQuaternion
        for i in rows.tolist():
            pos, quat = p.getBasePositionAndOrientation(bodies[i], cid)
            lin, ang = p.getBaseVelocity(bodies[i], cid)
            flat += pos
            flat += ang
            flat += lin
            flat += quat
            flat += rot(quat)
        a = np.array(flat).reshape(len(rows), 22).T
        if len(rows) == self.n:
            self._p, self._wv, self._quat, self._r9 = a[0:3], a[3:9], a[9:13].T, a[13:22]
        else:
            self._p[:, rows], self._wv[:, rows], self._quat[rows], self._r9[:, rows] = a[0:3], a[3:9], a[9:13].T, a[13:22]

    def _mode_masks(self) -> tuple:
        """(flying, any flying, all flying, velocity mask or None, land mask or None, idle spin,
        per-step rows): the commands change between steps, not between substeps (a touch-down
        clears them). The rows: targets (3, N), speed limits, cosines and sines of the yaws,
        velocity commands (3, N)."""
        if self._masks is None:
            flying = self.armed & (self.mode != IDLE)
            velocity, land = self.mode == VELOCITY, self.mode == LAND
            spin = np.repeat((self.armed * (0.15 * self.af.max_omega))[None], 4, axis=0)
            rows = (np.ascontiguousarray(self.target.T), self.ctrl.speed_limits(self.speed), np.cos(self.yaw),
                    np.sin(self.yaw), np.ascontiguousarray(self.vel_cmd.T))
            self._masks = (flying, bool(flying.any()), bool(flying.all()), velocity if velocity.any() else None,
                           land if land.any() else None, spin, rows)
        return self._masks

    #: np.take rows: R^T w from (9, N) rotations and (6, N) (w, v), and R b from a (3, N) b
    _WB_R, _WB_W = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8]), np.array([0, 0, 0, 1, 1, 1, 2, 2, 2])
    _RB_B = np.array([0, 1, 2, 0, 1, 2, 0, 1, 2])
    #: (9, N) matrices(q) (world to body) -> body to world, row major: the transpose
    _TRANSPOSE = np.array([0, 3, 6, 1, 4, 7, 2, 5, 8])

    def _substep(self) -> None:
        """One 240 Hz step of every vehicle, component-first arrays throughout (few numpy calls,
        each on contiguous rows: with 16 vehicles a call costs more than its arithmetic)."""
        h, af = 1.0 / PHYSICS_HZ, self.af
        pos, wv, r9 = self._p, self._wv, self._r9
        lin = wv[3:6]
        flying, any_flying, all_flying, velocity, land, spin, rows = self._mode_masks()
        w_cmd = spin.copy()  # idle spin, or stopped
        if any_flying:
            target, vmax, cos_yaw, sin_yaw, vel_cmd = rows
            prod = r9.take(self._WB_R, axis=0) * wv.take(self._WB_W, axis=0)  # R[i, j] w_i
            wb = (prod[0:3] + prod[3:6]) + prod[6:9]  # R^T w: body rates
            vel_sp = self.ctrl.velocity_setpoint_rows(pos, target, vmax)
            if velocity is not None:
                vel_sp[:, velocity] = vel_cmd[:, velocity]
            if land is not None:  # hold horizontal position, descend
                vel_sp[0:2, land] = 0.0
                vel_sp[2, land] = np.where(pos[2, land] > 1.0, -0.7, -0.4)
            held = self.ctrl.vi
            thrust, torque = self.ctrl.thrust_and_torque_rows(r9, lin, wb, vel_sp, cos_yaw, sin_yaw, h)
            if not all_flying:  # only flying vehicles integrate
                self.ctrl.vi[:, ~flying] = held[:, ~flying]
            f = self._alloc_inv @ np.concatenate((thrust[None], torque))  # (4, N) rotor thrusts
            w_fly = np.sqrt(np.maximum(f, 0.0) * (1.0 / af.kf))
            if all_flying:
                w_cmd = w_fly
            else:
                w_cmd[:, flying] = w_fly[:, flying]
        np.minimum(w_cmd, af.max_omega, out=w_cmd)
        self._om += (w_cmd - self._om) * self._lag
        q = self._om * self._om
        bt = self._rotor_torque @ q  # body torque (3, N)
        prod = r9 * bt.take(self._RB_B, axis=0)  # R[i, j] b_j
        load = np.empty((6, self.n))  # torque, force: world, at the centre of mass
        np.add(prod[0::3] + prod[1::3], prod[2::3], out=load[0:3])
        np.subtract(r9[2::3] * (q.sum(axis=0) * af.kf), lin * af.drag, out=load[3:6])
        n_free, bullet, bullet_list, thr = self._split
        if n_free < self.n:  # PyBullet steps the vehicles near the ground
            cid, bodies = self.cid, self.bodies
            lp = np.concatenate((load, pos)).T.take(bullet, axis=0).tolist() if n_free else \
                np.concatenate((load, pos)).T.tolist()
            for i, row in zip(bullet_list, lp, strict=True):
                p.applyExternalForce(bodies[i], -1, row[3:6], row[6:9], _WORLD_FRAME, cid)
                p.applyExternalTorque(bodies[i], -1, row[0:3], _WORLD_FRAME, cid)
            p.stepSimulation(cid)
        if n_free:  # fresh arrays: pos and lin above stay this substep's start for the touch-down check
            p1, q1, wv1, m1 = self._free_flight.step(pos, self._q, wv, load, self._m)
            # M(q)^T: exactly the matrix of conj(q), the orientation PyBullet would report
            self._p, self._q, self._wv, self._r9, self._m = p1, q1, wv1, m1.take(self._TRANSPOSE, axis=0), m1
        if n_free < self.n:  # the others' rows from PyBullet (their q rows are unused)
            self._read_bullet(bullet)
        self.time += h
        if land is not None:
            touch = land & self.armed & (pos[2] < af.size[2] / 2 + 0.03) & (np.abs(lin[2]) < 0.2)
            for i in np.flatnonzero(touch):
                self.disarm(int(i), force=True)
        if self._free_flight is not None:
            # a vehicle changes sides only when it crosses its threshold: free ones below
            # BULLET_BELOW_M, the others above FREE_ABOVE_M (thr holds each one's)
            flip = self.free == (self._p[2] < thr)
            if flip.any() and (n_free or flip.sum() >= self.free_flight_min):
                self._switch()

    def _switch(self) -> None:
        """Vehicles that climbed above FREE_ABOVE_M go to the numpy step: Bullet's m_baseQuat is
        the conjugate of the orientation PyBullet reported (equal to the last bit or so: the
        report went through a matrix). Vehicles that came down below BULLET_BELOW_M go back:
        their bodies are put where the numpy step has them (resetBasePositionAndOrientation
        stores conj(q), which is q exactly) with its velocities. A free vehicle has no PyBullet
        body: it is removed on the way up and made again on the way down."""
        z, free = self._p[2], self.free
        # who may fly free: in the air; all of them, if they are enough to pay for the numpy step
        want = np.where(free, z >= self.BULLET_BELOW_M, z > self.FREE_ABOVE_M)
        if want.sum() < (self.free_flight_min - 2 if free.any() else self.free_flight_min):
            want[:] = False
        up, down = want & ~free, free & ~want
        if up.any():
            qr = self._quat[up].T
            self._q[:, up] = [-qr[0], -qr[1], -qr[2], qr[3]]
            self.free |= up
            self._m = None
            # its PyBullet body goes: left in the world it would cost PyBullet its integration and
            # broadphase every step while other vehicles are on the ground
            for i in np.flatnonzero(up).tolist():
                p.removeBody(self.bodies[i], physicsClientId=self.cid)
                self.bodies[i] = None
        if down.any():
            cid = self.cid
            for i in np.flatnonzero(down).tolist():
                x, y, zq, w = self._q[:, i].tolist()
                pos, orn = self._p[:, i].tolist(), (-x, -y, -zq, w)
                b = self.bodies[i] = self._body(pos, orn)
                # createMultiBody stores the orientation through a matrix; the reset stores
                # conj(orn) = q exactly
                p.resetBasePositionAndOrientation(b, pos, orn, cid)
                p.resetBaseVelocity(b, self._wv[3:6, i].tolist(), self._wv[0:3, i].tolist(), cid)
            self.free &= ~down
            self._m = None
        if up.any() or down.any():
            self._set_split()

    def _set_split(self) -> None:
        """(vehicles free, indices and list of the others, each one's switching height): what
        a substep needs of `free`, made when it changes."""
        free = self.free
        bullet = np.flatnonzero(~free)
        self._split = (int(free.sum()), bullet, bullet.tolist(),
                       np.where(free, self.BULLET_BELOW_M, self.FREE_ABOVE_M))

    def _update_states(self) -> None:
        """What the states read, as (N, 3) views of one fresh (12, N) array (positions NED,
        velocities NED, roll/pitch/yaw, body rates FRD): a few calls on rows, no per-vehicle
        Python; fresh every step, so no state's arrays are shared with the next step's."""
        r9, wv, p_ = self._r9, self._wv, self._p
        gz = self.af.size[2] / 2
        out = np.empty((12, self.n))
        ned, vel, rpy, rates = out[0:3], out[3:6], out[6:9], out[9:12]
        np.subtract(p_.take(self._NED, axis=0), self._off_ned, out=ned)  # (y, x, z) - offsets
        np.subtract(gz, ned[2], out=ned[2])  # height above the ground -> down
        wv.take(self._NED_V, axis=0, out=vel)
        np.negative(vel[2], out=vel[2])
        prod = r9.take(self._WB_R, axis=0) * wv.take(self._WB_W, axis=0)
        np.add(prod[0:3] + prod[3:6], prod[6:9], out=rates)  # R^T w, FLU
        np.negative(rates[1:3], out=rates[1:3])  # -> FRD
        # roll, pitch, yaw of the FLU body in ENU from R = Rz(yaw) Ry(pitch) Rx(roll); NED: -pitch,
        # pi/2 - yaw wrapped to [-pi, pi)
        np.arctan2(r9[7], r9[8], out=rpy[0])
        np.arcsin(np.minimum(np.maximum(-r9[6], -1.0), 1.0), out=rpy[1])
        np.negative(rpy[1], out=rpy[1])
        yaw = np.arctan2(r9[3], r9[0])
        np.subtract((np.pi / 2 - yaw + np.pi) % (2 * np.pi), np.pi, out=rpy[2])
        self.landed = (p_[2] < gz + 0.05) & (np.abs(wv[5]) < 0.3)
        self.positions_ned, self.velocities_ned, self.attitudes_rpy, self.body_rates = ned.T, vel.T, rpy.T, rates.T
        np.add(self.battery_remaining * 2.8, 14.0, out=self.battery_voltage)  # as PyBulletQuadrotor sets it

    #: rows of the NED position (y, x, z of ENU) and velocity (vy, vx, vz of the (w, v) rows)
    _NED, _NED_V = np.array([1, 0, 2]), np.array([4, 3, 5])

    @property
    def omega(self) -> np.ndarray:
        """(N, 4) rotor speeds, rad/s (a view)."""
        return self._om.T

    @property
    def rotations(self) -> np.ndarray:
        """(N, 3, 3) body-to-world rotations now."""
        return self._r9.T.reshape(-1, 3, 3)

    @property
    def motor_thrusts(self) -> np.ndarray:
        """(N, 4) rotor thrusts now, N."""
        return self.af.kf * self.omega**2

    def close(self) -> None:
        if p.isConnected(self.cid):
            p.disconnect(self.cid)


class ArrayState:
    """A kinematic fleet member's VehicleState (the same fields), read from the fleet's arrays,
    so a fleet step writes no per-vehicle Python (100 states cost a third of a 100-vehicle
    fleet's step). Positions and velocities are rows of arrays made fresh every step, as the
    copies a lone vehicle's state holds; attitude and body rates are the state's own arrays."""

    __slots__ = ("_f", "_i", "attitude_rpy", "body_rates")

    def __init__(self, fleet: KinematicFleet, i: int) -> None:
        self._f, self._i = fleet, i
        self.attitude_rpy, self.body_rates = np.zeros(3), np.zeros(3)

    @property
    def time_s(self) -> float:
        return self._f.time

    @property
    def position_ned(self) -> np.ndarray:
        return self._f.positions_ned[self._i]

    @property
    def velocity_ned(self) -> np.ndarray:
        return self._f.velocities_ned[self._i]

    @property
    def armed(self) -> bool:
        return bool(self._f.armed[self._i])

    @property
    def landed(self) -> bool:
        return bool(self._f.landed[self._i])

    @property
    def battery_remaining(self) -> float:
        return float(self._f.battery_remaining[self._i])

    @battery_remaining.setter
    def battery_remaining(self, value: float) -> None:
        self._f.battery_remaining[self._i] = value

    @property
    def battery_voltage(self) -> float:
        return float(self._f.battery_voltage[self._i])

    @battery_voltage.setter
    def battery_voltage(self, value: float) -> None:
        self._f.battery_voltage[self._i] = value

    def __repr__(self) -> str:
        return (f"ArrayState(vehicle {self._i}, position_ned={self.position_ned}, velocity_ned={self.velocity_ned}, "
                f"armed={self.armed}, landed={self.landed}, battery_remaining={self.battery_remaining:.4f})")


class QuadState(ArrayState):
    """A QuadrotorFleet member's VehicleState: everything read from the fleet's arrays, attitude
    and body rates too (rows of arrays made fresh every step), so a step writes no per-vehicle
    Python (16 states cost ~30 us a step). Armed and landed are the fleet's flags."""

    __slots__ = ()

    def __init__(self, fleet: QuadrotorFleet, i: int) -> None:  # no arrays of its own
        self._f, self._i = fleet, i

    @property
    def attitude_rpy(self) -> np.ndarray:
        return self._f.attitudes_rpy[self._i]

    @property
    def body_rates(self) -> np.ndarray:
        return self._f.body_rates[self._i]


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
        # what the states read (ArrayState): made fresh every step, never changed in place
        self.positions_ned, self.velocities_ned = self.pos.copy(), self.vel.copy()
        self.landed = np.ones(n, dtype=bool)
        self.battery_remaining, self.battery_voltage = np.ones(n), np.full(n, 16.8)  # VehicleState's defaults
        self.states = [ArrayState(self, i) for i in range(n)]
        self.members = [FleetMember(self, i) for i in range(n)]

    def arm(self, i: int) -> bool:
        if not self.armed[i]:
            self.armed[i] = True
            self.target[i] = self.pos[i]
            self.mode[i] = POSITION
        return True

    def disarm(self, i: int, force: bool = False) -> bool:
        if not self.states[i].landed and not force:
            return False
        self.armed[i] = False
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
        if a.all():  # the same sums without the masks (fancy indexing is most of a small step)
            self.vel += dv
            self.pos += self.vel * dt
        else:
            self.vel[a] += dv[a]
            self.vel[~a] = 0.0
            self.pos[a] += self.vel[a] * dt
        down = a & (self.pos[:, 2] >= 0.0)
        self.pos[down, 2] = 0.0
        self.vel[down, 2] = np.minimum(self.vel[down, 2], 0.0)
        landed = np.where(a, down, self.landed)
        for i in np.flatnonzero(down & (self.mode == LAND)):
            self.armed[i] = False
            self.mode[i] = IDLE
        # the states read these (ArrayState): fresh arrays, never shared with the next step
        self.positions_ned, self.velocities_ned, self.landed = self.pos.copy(), self.vel.copy(), landed
        yawed = a & np.isfinite(self.yaw)
        for i in np.flatnonzero(yawed).tolist():
            self.states[i].attitude_rpy[2] = self.yaw[i]
        if a.any():  # the model's own battery (the MAVLink side keeps its own): armed vehicles drain
            r = np.maximum(0.0, self.battery_remaining[a] - dt / 1800.0)
            self.battery_remaining[a] = r
            self.battery_voltage[a] = 14.0 + 2.8 * r

    def close(self) -> None:
        pass
