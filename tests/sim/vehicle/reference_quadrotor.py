"""The quadrotor's original numpy maths (controller and force application, as shipped before
issue 13's rewrite), kept as the reference the fast float and batched versions are checked
against: same setpoints in, same trajectories out."""

from __future__ import annotations

import numpy as np
import pybullet as p

from sim.vehicle.controller import G, Gains
from sim.vehicle.quadrotor import PHYSICS_HZ, PyBulletQuadrotor


def _rot_from_z_yaw(z_b: np.ndarray, yaw: float) -> np.ndarray:
    x_c = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    y_b = np.cross(z_b, x_c)
    n = np.linalg.norm(y_b)
    y_b = y_b / n if n > 1e-6 else np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    x_b = np.cross(y_b, z_b)
    return np.column_stack([x_b, y_b, z_b])


class ReferenceController:
    def __init__(self, mass: float, inertia: np.ndarray, gains: Gains | None = None) -> None:
        self.m, self.J, self.g = mass, np.asarray(inertia, dtype=float), gains or Gains()
        self.vel_int = np.zeros(3)

    def reset(self) -> None:
        self.vel_int[:] = 0.0

    def velocity_setpoint(self, pos: np.ndarray, target: np.ndarray, speed: float | None) -> np.ndarray:
        v = self.g.pos_p * (target - pos)
        vmax = min(self.g.max_speed, speed or self.g.max_speed)
        h = np.linalg.norm(v[:2])
        if h > vmax:
            v[:2] *= vmax / h
        v[2] = np.clip(v[2], -self.g.max_descent, self.g.max_climb)
        return v

    def thrust_and_torque(self, rot, vel, omega_body, vel_sp, yaw_sp, dt):
        g = self.g
        err = vel_sp - vel
        near = np.abs(err) < 0.5
        self.vel_int = np.clip(self.vel_int + np.where(near, err, 0.0) * dt, -2.0, 2.0)
        acc = g.vel_p * err + g.vel_i * self.vel_int
        az = np.clip(acc[2], -0.7 * G, 1.0 * G)
        hmax = np.tan(g.max_tilt) * (G + az)
        h = np.linalg.norm(acc[:2])
        if h > hmax:
            acc[:2] *= hmax / h
        f = self.m * np.array([acc[0], acc[1], az + G])
        z_des = f / np.linalg.norm(f)
        thrust = float(f @ rot[:, 2])
        r_des = _rot_from_z_yaw(z_des, yaw_sp)
        e = 0.5 * (r_des.T @ rot - rot.T @ r_des)
        att_err = -np.array([e[2, 1], e[0, 2], e[1, 0]])
        rate_sp = g.att_p * att_err
        rate_sp[2] = np.clip(rate_sp[2], -g.max_yaw_rate, g.max_yaw_rate)
        rate_err = rate_sp - omega_body
        torque = self.J @ (g.rate_p * rate_err) + np.cross(omega_body, self.J @ omega_body)
        torque[2] = np.clip(torque[2], -g.max_yaw_torque, g.max_yaw_torque)
        return max(thrust, 0.0), torque


class ReferenceQuadrotor(PyBulletQuadrotor):
    """PyBulletQuadrotor with the original per-substep numpy code path."""

    def __init__(self, *args, **kw) -> None:
        super().__init__(*args, **kw)
        self.ref = ReferenceController(self.af.mass, self.J)
        d = self.af.arm / np.sqrt(2)
        self.rotors_np = np.array([[d, -d, 0], [-d, d, 0], [d, d, 0], [-d, -d, 0]], dtype=float)
        self.spin_np = np.array([1, 1, -1, -1], dtype=float)
        alloc = np.vstack([np.ones(4), self.rotors_np[:, 1], -self.rotors_np[:, 0],
                           self.spin_np * self.af.km / self.af.kf])
        self.alloc_inv_np = np.linalg.inv(alloc)
        self.omega_np = np.zeros(4)

    def arm(self) -> bool:
        ok = super().arm()
        self.ref.reset()
        return ok

    def disarm(self, force: bool = False) -> bool:
        ok = super().disarm(force)
        if ok:
            self.omega_np[:] = 0.0
        return ok

    def _substep(self) -> None:
        h = 1.0 / PHYSICS_HZ
        pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.cid)
        pos, lin, ang = np.array(pos), np.array(lin), np.array(ang)
        rot = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        omega_b = rot.T @ ang
        if self._s.armed and self._mode != "idle":
            if self._mode == "position":
                vel_sp = self.ref.velocity_setpoint(pos, np.asarray(self._target_enu), self._speed)
            elif self._mode == "velocity":
                vel_sp = np.asarray(self._vel_enu)
            else:
                vel_sp = np.array([0.0, 0.0, -0.7 if pos[2] > 1.0 else -0.4])
            thrust, torque = self.ref.thrust_and_torque(rot, lin, omega_b, vel_sp, self._yaw_enu, h)
            f = self.alloc_inv_np @ np.array([thrust, *torque])
            w_cmd = np.sqrt(np.clip(f, 0.0, None) / self.af.kf)
        elif self._s.armed:
            w_cmd = np.full(4, 0.15 * self.af.max_omega)
        else:
            w_cmd = np.zeros(4)
        w_cmd = np.clip(w_cmd, 0.0, self.af.max_omega)
        self.omega_np += (w_cmd - self.omega_np) * min(1.0, h / self.af.motor_tau)
        thrusts = self.af.kf * self.omega_np**2
        self.omega = self.omega_np.tolist()
        for r, f in zip(self.rotors_np, thrusts, strict=True):
            p.applyExternalForce(self.body, -1, [0, 0, float(f)], r.tolist(), p.LINK_FRAME, physicsClientId=self.cid)
        yaw_torque = float(np.sum(self.spin_np * self.af.km * self.omega_np**2))
        world_torque = rot @ np.array([0.0, 0.0, yaw_torque])
        p.applyExternalTorque(self.body, -1, world_torque.tolist(), p.WORLD_FRAME, physicsClientId=self.cid)
        drag = -self.af.drag * lin
        p.applyExternalForce(self.body, -1, drag.tolist(), pos.tolist(), p.WORLD_FRAME, physicsClientId=self.cid)
        p.stepSimulation(physicsClientId=self.cid)
        self.time += h
        if self._mode == "land" and self._s.armed:
            if pos[2] < self.af.size[2] / 2 + 0.03 and abs(lin[2]) < 0.2:
                self.disarm(force=True)
