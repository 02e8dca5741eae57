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


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def _bclip(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """np.clip without its Python-level dispatch (which costs ten ufunc calls on small arrays)."""
    return np.minimum(np.maximum(x, lo), hi)


class CascadedController:
    """One vehicle. Rotation matrices are PyBullet's getMatrixFromQuaternion: 9 floats, row
    major, body to world."""

    def __init__(self, mass: float, inertia: np.ndarray, gains: Gains | None = None) -> None:
        self.m, self.J, self.g = float(mass), np.asarray(inertia, dtype=float), gains or Gains()
        if self.J.shape != (3, 3):
            raise ValueError(f"inertia must be 3 x 3 (got shape {self.J.shape})")
        self._j = tuple(float(x) for x in self.J.ravel())
        self.vel_int = [0.0, 0.0, 0.0]

    def reset(self) -> None:
        self.vel_int = [0.0, 0.0, 0.0]

    def velocity_setpoint(self, pos: Sequence[float], target: Sequence[float], speed: float | None) -> Vec3:
        g = self.g
        vx, vy, vz = g.pos_p * (target[0] - pos[0]), g.pos_p * (target[1] - pos[1]), g.pos_p * (target[2] - pos[2])
        vmax = min(g.max_speed, speed or g.max_speed)
        h = math.hypot(vx, vy)
        if h > vmax:
            vx, vy = vx * (vmax / h), vy * (vmax / h)
        return vx, vy, _clip(vz, -g.max_descent, g.max_climb)

    def thrust_and_torque(
        self, rot: Sequence[float], vel: Sequence[float], omega_body: Sequence[float], vel_sp: Sequence[float],
        yaw_sp: float, dt: float,
    ) -> tuple[float, Vec3]:
        """Collective thrust (N) and body torques (N m) tracking a velocity and a yaw."""
        g = self.g
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
        ax, ay = g.vel_p * ex + g.vel_i * ix, g.vel_p * ey + g.vel_i * iy
        # limit tilt: horizontal acceleration bounded by tan(max_tilt) * (g + a_z)
        az = _clip(g.vel_p * ez + g.vel_i * iz, -0.7 * G, 1.0 * G)
        hmax = math.tan(g.max_tilt) * (G + az)
        h = math.hypot(ax, ay)
        if h > hmax:
            ax, ay = ax * (hmax / h), ay * (hmax / h)
        fx, fy, fz = self.m * ax, self.m * ay, self.m * (az + G)
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
        kp, kr = g.att_p, g.rate_p
        wx, wy, wz = omega_body
        qx = kr * (-kp * e21 - wx)
        qy = kr * (-kp * e02 - wy)
        qz = kr * (_clip(-kp * e10, -g.max_yaw_rate, g.max_yaw_rate) - wz)
        j00, j01, j02, j10, j11, j12, j20, j21, j22 = self._j
        hx, hy, hz = j00 * wx + j01 * wy + j02 * wz, j10 * wx + j11 * wy + j12 * wz, j20 * wx + j21 * wy + j22 * wz
        tx = j00 * qx + j01 * qy + j02 * qz + (wy * hz - wz * hy)
        ty = j10 * qx + j11 * qy + j12 * qz + (wz * hx - wx * hz)
        tz = j20 * qx + j21 * qy + j22 * qz + (wx * hy - wy * hx)
        # yaw authority comes from differential rotor drag: never let it starve thrust or tilt
        tz = _clip(tz, -g.max_yaw_torque, g.max_yaw_torque)
        return max(thrust, 0.0), (tx, ty, tz)


class BatchController:
    """N vehicles with the same airframe: every argument carries a leading vehicle axis.
    Rotation matrices (N, 3, 3) body to world."""

    def __init__(self, n: int, mass: float, inertia: np.ndarray, gains: Gains | None = None) -> None:
        if n < 1:
            raise ValueError(f"a batch needs at least one vehicle (got {n})")
        self.n, self.m, self.g = n, float(mass), gains or Gains()
        self.J = np.asarray(inertia, dtype=float)
        if self.J.shape != (3, 3):
            raise ValueError(f"inertia must be 3 x 3 (got shape {self.J.shape})")
        self.vel_int = np.zeros((n, 3))

    def reset(self, which: np.ndarray | slice | int = slice(None)) -> None:
        self.vel_int[which] = 0.0

    def velocity_setpoint(self, pos: np.ndarray, target: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """speed (N,): per-vehicle limit, NaN or <= 0 for the default."""
        g = self.g
        v = g.pos_p * (target - pos)
        vmax = np.where(np.isfinite(speed) & (speed > 0), np.minimum(speed, g.max_speed), g.max_speed)
        h = np.hypot(v[:, 0], v[:, 1])
        scale = np.where(h > vmax, vmax / np.maximum(h, 1e-300), 1.0)
        v[:, :2] *= scale[:, None]
        v[:, 2] = _bclip(v[:, 2], -g.max_descent, g.max_climb)
        return v

    def thrust_and_torque(
        self, rot: np.ndarray, vel: np.ndarray, omega_body: np.ndarray, vel_sp: np.ndarray, yaw_sp: np.ndarray,
        dt: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N,) thrusts and (N, 3) body torques. Written component by component on (N,)
        arrays: with tens of vehicles every numpy call costs more than its arithmetic, and
        stack, einsum and cross cost several plain ones."""
        g = self.g
        err = vel_sp - vel
        vi = self.vel_int + err * dt * (np.abs(err) < 0.5)  # integrate only near the setpoint
        vi = _bclip(vi, -2.0, 2.0)
        self.vel_int = vi
        acc = g.vel_p * err + g.vel_i * vi
        az = _bclip(acc[:, 2], -0.7 * G, 1.0 * G)
        hmax = math.tan(g.max_tilt) * (G + az)
        h = np.hypot(acc[:, 0], acc[:, 1])
        ms = self.m * np.minimum(1.0, hmax / np.maximum(h, 1e-300))  # tilt limit
        fx, fy, fz = ms * acc[:, 0], ms * acc[:, 1], self.m * (az + G)
        r00, r01, r02 = rot[:, 0, 0], rot[:, 0, 1], rot[:, 0, 2]
        r10, r11, r12 = rot[:, 1, 0], rot[:, 1, 1], rot[:, 1, 2]
        r20, r21, r22 = rot[:, 2, 0], rot[:, 2, 1], rot[:, 2, 2]
        thrust = fx * r02 + fy * r12 + fz * r22
        inv = 1.0 / np.sqrt(fx * fx + fy * fy + fz * fz)
        zx, zy, zz = fx * inv, fy * inv, fz * inv
        c, s = np.cos(yaw_sp), np.sin(yaw_sp)
        yx, yy, yz = -zz * s, zz * c, zx * s - zy * c
        n = np.sqrt(yx * yx + yy * yy + yz * yz)
        ok = n > 1e-6
        if ok.all():
            yx, yy, yz = yx / n, yy / n, yz / n
        else:  # force along the yaw axis: any heading will do
            safe = np.where(ok, n, 1.0)
            yx, yy, yz = np.where(ok, yx / safe, -s), np.where(ok, yy / safe, c), np.where(ok, yz / safe, 0.0)
        xx, xy, xz = yy * zz - yz * zy, yz * zx - yx * zz, yx * zy - yy * zx
        e21 = (zx * r01 + zy * r11 + zz * r21) - (r02 * yx + r12 * yy + r22 * yz)
        e02 = (xx * r02 + xy * r12 + xz * r22) - (r00 * zx + r10 * zy + r20 * zz)
        e10 = (yx * r00 + yy * r10 + yz * r20) - (r01 * xx + r11 * xy + r21 * xz)
        k = -0.5 * g.att_p
        rate_sp = np.empty_like(err)
        rate_sp[:, 0], rate_sp[:, 1] = k * e21, k * e02
        rate_sp[:, 2] = _bclip(k * e10, -g.max_yaw_rate, g.max_yaw_rate)
        w = omega_body
        hw = w @ self.J.T
        torque = (g.rate_p * (rate_sp - w)) @ self.J.T
        torque[:, 0] += w[:, 1] * hw[:, 2] - w[:, 2] * hw[:, 1]
        torque[:, 1] += w[:, 2] * hw[:, 0] - w[:, 0] * hw[:, 2]
        torque[:, 2] += w[:, 0] * hw[:, 1] - w[:, 1] * hw[:, 0]
        torque[:, 2] = _bclip(torque[:, 2], -g.max_yaw_torque, g.max_yaw_torque)
        return np.maximum(thrust, 0.0), torque
