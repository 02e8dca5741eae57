"""Cascaded multicopter control, as PX4's and ArduPilot's: position -> velocity ->
acceleration/thrust vector -> attitude -> body rates -> torques. All in the ENU world frame and
the FLU body frame; gains chosen for the 1.5 kg airframe in quadrotor.py.

Two implementations of the same maths (tests/sim/vehicle/reference_quadrotor.py keeps the
original numpy one and the tests fly all three through the same setpoints):
- `CascadedController`: one vehicle, plain floats and the math module. At 240 Hz the
  controller runs on 3-vectors, where every numpy call costs more than the arithmetic it does
  (np.cross alone took ten times PyBullet's own step; docs/vehicle.md has the profile).
- `BatchController`: N vehicles at once, numpy over the vehicle axis (the fleet in fleet.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

G = 9.81

Vec3 = tuple[float, float, float]


@dataclass
class Gains:
    pos_p: float = 1.2
    vel_p: float = 3.0
    vel_i: float = 4.0
    att_p: float = 7.0
    rate_p: float = 25.0
    max_tilt: float = np.radians(30)
    max_speed: float = 5.0
    max_climb: float = 2.0
    max_descent: float = 1.5
    max_yaw_rate: float = np.radians(60)
    max_yaw_torque: float = 0.05


class CascadedController:
    """One vehicle. Rotation matrices are PyBullet's getMatrixFromQuaternion: 9 floats, row
    major, body to world."""

    def __init__(self, mass: float, inertia: np.ndarray, gains: Gains | None = None) -> None:
        self.m, self.J, self.g = float(mass), np.asarray(inertia, dtype=float), gains or Gains()
        if self.J.shape != (3, 3):
            raise ValueError(f"inertia must be 3 x 3 (got shape {self.J.shape})")
        self._j = tuple(float(x) for x in self.J.ravel())
        # a diagonal J (the airframe's box): J w is (j00 wx, j11 wy, j22 wz), the same numbers as
        # the full product (the other terms add zeros), 18 float operations fewer a call
        self._jdiag = not any(self._j[i] for i in (1, 2, 3, 5, 6, 7))
        self.vel_int = [0.0, 0.0, 0.0]
        self.refresh_gains()

    def refresh_gains(self) -> None:
        """Cache the gains as plain floats (attribute lookups cost as much as the arithmetic at
        240 Hz); call again after changing `self.g`."""
        g = self.g
        self._tan_tilt = math.tan(g.max_tilt)
        self._gains = (g.vel_p, g.vel_i, g.att_p, g.rate_p, g.max_yaw_rate, g.max_yaw_torque)

    def reset(self) -> None:
        self.vel_int = [0.0, 0.0, 0.0]

    def velocity_setpoint(self, pos: Sequence[float], target: Sequence[float], speed: float | None) -> Vec3:
        g = self.g
        k = g.pos_p
        vx, vy, vz = k * (target[0] - pos[0]), k * (target[1] - pos[1]), k * (target[2] - pos[2])
        vmax = g.max_speed if not speed or speed > g.max_speed else speed
        h = math.hypot(vx, vy)
        if h > vmax:
            vx, vy = vx * (vmax / h), vy * (vmax / h)
        lo, hi = -g.max_descent, g.max_climb
        return vx, vy, (lo if vz < lo else hi if vz > hi else vz)

    def thrust_and_torque(
        self, rot: Sequence[float], vel: Sequence[float], omega_body: Sequence[float], vel_sp: Sequence[float],
        yaw_sp: float, dt: float,
    ) -> tuple[float, Vec3]:
        """Collective thrust (N) and body torques (N m) tracking a velocity and a yaw."""
        vel_p, vel_i, att_p, rate_p, max_yaw_rate, max_yaw_torque = self._gains
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
        ex, ey, ez = vel_sp[0] - vel[0], vel_sp[1] - vel[1], vel_sp[2] - vel[2]
        # integrate only near the setpoint, so take-off and long legs do not wind it up
        ix, iy, iz = self.vel_int
        # (inline clips: a function call per clip costs as much as the rest of the line)
        if -0.5 < ex < 0.5:
            ix += ex * dt
            ix = -2.0 if ix < -2.0 else 2.0 if ix > 2.0 else ix
        if -0.5 < ey < 0.5:
            iy += ey * dt
            iy = -2.0 if iy < -2.0 else 2.0 if iy > 2.0 else iy
        if -0.5 < ez < 0.5:
            iz += ez * dt
            iz = -2.0 if iz < -2.0 else 2.0 if iz > 2.0 else iz
        self.vel_int = [ix, iy, iz]
        ax, ay = vel_p * ex + vel_i * ix, vel_p * ey + vel_i * iy
        # limit tilt: horizontal acceleration bounded by tan(max_tilt) * (g + a_z)
        az = vel_p * ez + vel_i * iz
        az = -0.7 * G if az < -0.7 * G else G if az > G else az
        hmax = self._tan_tilt * (G + az)
        h = math.hypot(ax, ay)
        if h > hmax:
            ax, ay = ax * (hmax / h), ay * (hmax / h)
        m = self.m
        fx, fy, fz = m * ax, m * ay, m * (az + G)
        thrust = fx * r02 + fy * r12 + fz * r22
        n = math.sqrt(fx * fx + fy * fy + fz * fz)
        zx, zy, zz = fx / n, fy / n, fz / n
        # desired attitude: body z along the force, nose towards the yaw (x_c), y = z x x_c
        c, s = math.cos(yaw_sp), math.sin(yaw_sp)
        yx, yy, yz = -zz * s, zz * c, zx * s - zy * c
        n = math.sqrt(yx * yx + yy * yy + yz * yz)
        if n > 1e-6:
            yx, yy, yz = yx / n, yy / n, yz / n
        else:
            yx, yy, yz = -s, c, 0.0
        xx, xy, xz = yy * zz - yz * zy, yz * zx - yx * zz, yx * zy - yy * zx
        # attitude error: vee(R_des^T R - R^T R_des) / 2, with (A^T B)_ij = col_i(A) . col_j(B)
        e21 = 0.5 * ((zx * r01 + zy * r11 + zz * r21) - (r02 * yx + r12 * yy + r22 * yz))
        e02 = 0.5 * ((xx * r02 + xy * r12 + xz * r22) - (r00 * zx + r10 * zy + r20 * zz))
        e10 = 0.5 * ((yx * r00 + yy * r10 + yz * r20) - (r01 * xx + r11 * xy + r21 * xz))
        wx, wy, wz = omega_body
        qx = rate_p * (-att_p * e21 - wx)
        qy = rate_p * (-att_p * e02 - wy)
        rz = -att_p * e10
        qz = rate_p * ((-max_yaw_rate if rz < -max_yaw_rate else max_yaw_rate if rz > max_yaw_rate else rz) - wz)
        j00, j01, j02, j10, j11, j12, j20, j21, j22 = self._j
        if self._jdiag:
            hx, hy, hz = j00 * wx, j11 * wy, j22 * wz
            tx = j00 * qx + (wy * hz - wz * hy)
            ty = j11 * qy + (wz * hx - wx * hz)
            tz = j22 * qz + (wx * hy - wy * hx)
        else:
            hx, hy, hz = (j00 * wx + j01 * wy + j02 * wz, j10 * wx + j11 * wy + j12 * wz,
                          j20 * wx + j21 * wy + j22 * wz)
            tx = j00 * qx + j01 * qy + j02 * qz + (wy * hz - wz * hy)
            ty = j10 * qx + j11 * qy + j12 * qz + (wz * hx - wx * hz)
            tz = j20 * qx + j21 * qy + j22 * qz + (wx * hy - wy * hx)
        # yaw authority comes from differential rotor drag: never let it starve thrust or tilt
        tz = -max_yaw_torque if tz < -max_yaw_torque else max_yaw_torque if tz > max_yaw_torque else tz
        return (thrust if thrust > 0.0 else 0.0), (tx, ty, tz)


class BatchController:
    """N vehicles with the same airframe. The fleet calls the `_rows` methods: component-first
    arrays, (3, N) vectors and (9, N) row-major rotations body to world, so every numpy call is
    one plain operation on contiguous rows (with tens of vehicles each call costs more than its
    arithmetic, and broadcasting or strided views cost several times a plain call). The
    vehicle-first methods (N, 3) wrap them, for tests and other callers."""

    # np.take rows: cross products a x b of stacked (a 0-2, b 3-5): a_y b_z - a_z b_y, ...
    _CROSS_L, _CROSS_R = np.array([1, 2, 0, 2, 0, 1]), np.array([5, 3, 4, 4, 5, 3])
    # the attitude error's six dot products from (y 0-2, z 3-5, x 6-8) and the rotation's columns:
    # z.c1, y.c2 | x.c2, z.c0 | y.c0, x.c1, each as three products summed in order
    _DOT_L = np.array([[3, 0, 6, 3, 0, 6], [4, 1, 7, 4, 1, 7], [5, 2, 8, 5, 2, 8]]).ravel()
    _DOT_R = np.array([[1, 2, 2, 0, 0, 1], [4, 5, 5, 3, 3, 4], [7, 8, 8, 6, 6, 7]]).ravel()

    def __init__(self, n: int, mass: float, inertia: np.ndarray, gains: Gains | None = None) -> None:
        if n < 1:
            raise ValueError(f"a batch needs at least one vehicle (got {n})")
        self.n, self.m, self.g = n, float(mass), gains or Gains()
        self.J = np.asarray(inertia, dtype=float)
        if self.J.shape != (3, 3):
            raise ValueError(f"inertia must be 3 x 3 (got shape {self.J.shape})")
        diagonal = not (self.J - np.diag(np.diag(self.J))).any()
        # J as rows to multiply by (J w for a diagonal J is J_ii w_i: the same numbers as J @ w)
        self._jd = np.repeat(np.diag(self.J)[:, None], n, axis=1) if diagonal else None
        self.vi = np.zeros((3, n))  # velocity integrators, component first
        self.refresh_gains()

    def refresh_gains(self) -> None:
        """Cache the gains and limits as 0-d arrays: an operation with a Python float converts it
        every call (~0.2 us of a ~0.35 us operation on tens of vehicles); the same values and
        results. Call again after changing `self.g`."""
        g = self.g
        self._k = {name: np.array(float(v)) for name, v in {
            "tan_tilt": math.tan(g.max_tilt), "m": self.m, "g": G, "vel_p": g.vel_p, "vel_i": g.vel_i,
            "pos_p": g.pos_p, "att": -0.5 * g.att_p, "rate_p": g.rate_p, "one": 1.0, "half": 0.5, "two": 2.0,
            "-two": -2.0, "tiny": 1e-300, "az_lo": -0.7 * G, "az_hi": 1.0 * G, "yaw_rate": g.max_yaw_rate,
            "-yaw_rate": -g.max_yaw_rate, "yaw_torque": g.max_yaw_torque, "-yaw_torque": -g.max_yaw_torque,
            "climb": g.max_climb, "-descent": -g.max_descent}.items()}

    @property
    def vel_int(self) -> np.ndarray:
        """(N, 3) view of the velocity integrators."""
        return self.vi.T

    def reset(self, which: np.ndarray | slice | int = slice(None)) -> None:
        self.vi[:, which] = 0.0

    def speed_limits(self, speed: np.ndarray) -> np.ndarray:
        """(N,) horizontal speed limits from per-vehicle limits (NaN or <= 0 for the default)."""
        g = self.g
        return np.where(np.isfinite(speed) & (speed > 0), np.minimum(speed, g.max_speed), g.max_speed)

    def velocity_setpoint(self, pos: np.ndarray, target: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """speed (N,): per-vehicle limit, NaN or <= 0 for the default. (N, 3)."""
        return self.velocity_setpoint_rows(pos.T, target.T, self.speed_limits(speed)).T

    def velocity_setpoint_rows(self, pos: np.ndarray, target: np.ndarray, vmax: np.ndarray) -> np.ndarray:
        """(3, N) velocity setpoints for (3, N) positions and targets, vmax from speed_limits."""
        k = self._k
        v = (target - pos) * k["pos_p"]
        h = np.hypot(v[0], v[1])
        over = h > vmax
        if over.any():
            v[0:2] *= np.where(over, vmax / np.maximum(h, k["tiny"]), k["one"])
        np.minimum(np.maximum(v[2], k["-descent"], out=v[2]), k["climb"], out=v[2])
        return v

    def thrust_and_torque(
        self, rot: np.ndarray, vel: np.ndarray, omega_body: np.ndarray, vel_sp: np.ndarray, yaw_sp: np.ndarray,
        dt: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N,) thrusts and (N, 3) body torques; rot (N, 3, 3) body to world."""
        r9 = np.ascontiguousarray(rot.reshape(-1, 9).T)
        thrust, torque = self.thrust_and_torque_rows(r9, vel.T, omega_body.T, vel_sp.T, np.cos(yaw_sp),
                                                     np.sin(yaw_sp), dt)
        return thrust, torque.T

    def thrust_and_torque_rows(
        self, r9: np.ndarray, vel: np.ndarray, wb: np.ndarray, vel_sp: np.ndarray, cos_yaw: np.ndarray,
        sin_yaw: np.ndarray, dt: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N,) thrusts and (3, N) body torques tracking (3, N) velocity setpoints and yaws (given
        as their cosines and sines: they change between steps, not substeps); r9 (9, N) row-major
        rotations body to world, vel (3, N) world, wb (3, N) body rates. The maths of
        CascadedController, in the same order up to rounding."""
        k, m = self._k, self._k["m"]
        err = vel_sp - vel
        vi = self.vi + (err * dt) * (np.abs(err) < k["half"])  # integrate only near the setpoint
        np.minimum(np.maximum(vi, k["-two"], out=vi), k["two"], out=vi)
        self.vi = vi
        acc = err * k["vel_p"] + vi * k["vel_i"]
        az = np.minimum(np.maximum(acc[2], k["az_lo"]), k["az_hi"])
        hmax = (az + k["g"]) * k["tan_tilt"]  # tilt limit: horizontal acceleration <= tan(max_tilt) (g + a_z)
        h = np.hypot(acc[0], acc[1])
        f = np.empty_like(acc)
        np.multiply(acc[0:2], np.minimum(hmax / np.maximum(h, k["tiny"]), k["one"]) * m, out=f[0:2])
        np.multiply(az + k["g"], m, out=f[2])
        fr = f * r9[2::3]  # f . (r02, r12, r22): the thrust along the body z axis
        thrust = (fr[0] + fr[1]) + fr[2]
        ff = f * f
        z = f * (k["one"] / np.sqrt((ff[0] + ff[1]) + ff[2]))
        # desired attitude: body z along the force, nose towards the yaw (x_c), y = z x x_c
        yz = np.empty((6, z.shape[1]))  # y (0-2), then z (3-5)
        yz[3:6] = z
        np.multiply(z[2], sin_yaw, out=yz[0])
        np.negative(yz[0], out=yz[0])
        np.multiply(z[2], cos_yaw, out=yz[1])
        np.subtract(z[0] * sin_yaw, z[1] * cos_yaw, out=yz[2])
        yy = yz[0:3] * yz[0:3]
        n = np.sqrt((yy[0] + yy[1]) + yy[2])
        ok = n > 1e-6
        if ok.all():
            yz[0:3] /= n
        else:  # force along the yaw axis: any heading will do
            safe = np.where(ok, n, 1.0)
            yz[0:3] = np.where(ok, yz[0:3] / safe, [-sin_yaw, cos_yaw, np.zeros_like(cos_yaw)])
        prod = yz.take(self._CROSS_L, axis=0) * yz.take(self._CROSS_R, axis=0)
        yzx = np.concatenate((yz, prod[0:3] - prod[3:6]))  # y, z, x = y x z
        # attitude error: vee(R_des^T R - R^T R_des) / 2 from the six dot products
        prod = yzx.take(self._DOT_L, axis=0) * r9.take(self._DOT_R, axis=0)
        dots = (prod[0:6] + prod[6:12]) + prod[12:18]
        rate_sp = (dots[0::2] - dots[1::2]) * k["att"]  # from (e21, e02, e10)
        np.minimum(np.maximum(rate_sp[2], k["-yaw_rate"], out=rate_sp[2]), k["yaw_rate"], out=rate_sp[2])
        # rate loop through the inertia, plus the gyroscopic term w x J w
        if self._jd is not None:
            torque = (rate_sp - wb) * k["rate_p"] * self._jd
            wh = np.concatenate((wb, wb * self._jd))
        else:
            torque = self.J @ ((rate_sp - wb) * k["rate_p"])
            wh = np.concatenate((wb, self.J @ wb))
        prod = wh.take(self._CROSS_L, axis=0) * wh.take(self._CROSS_R, axis=0)
        torque += prod[0:3] - prod[3:6]
        # yaw authority comes from differential rotor drag: never let it starve thrust or tilt
        np.minimum(np.maximum(torque[2], k["-yaw_torque"], out=torque[2]), k["yaw_torque"], out=torque[2])
        return np.maximum(thrust, 0.0), torque
