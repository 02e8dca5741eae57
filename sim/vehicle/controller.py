"""Cascaded multicopter control, as PX4's and ArduPilot's: position -> velocity ->
acceleration/thrust vector -> attitude -> body rates -> torques. All in the ENU world frame and
the FLU body frame; gains chosen for the 1.5 kg airframe in quadrotor.py."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

G = 9.81


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


def _rot_from_z_yaw(z_b: np.ndarray, yaw: float) -> np.ndarray:
    x_c = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    y_b = np.cross(z_b, x_c)
    n = np.linalg.norm(y_b)
    y_b = y_b / n if n > 1e-6 else np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    x_b = np.cross(y_b, z_b)
    return np.column_stack([x_b, y_b, z_b])


class CascadedController:
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

    def thrust_and_torque(
        self, rot: np.ndarray, vel: np.ndarray, omega_body: np.ndarray, vel_sp: np.ndarray, yaw_sp: float, dt: float
    ) -> tuple[float, np.ndarray]:
        """Collective thrust (N) and body torques (N m) tracking a velocity and a yaw."""
        g = self.g
        err = vel_sp - vel
        # integrate only near the setpoint, so take-off and long legs do not wind it up
        near = np.abs(err) < 0.5
        self.vel_int = np.clip(self.vel_int + np.where(near, err, 0.0) * dt, -2.0, 2.0)
        acc = g.vel_p * err + g.vel_i * self.vel_int
        # limit tilt: horizontal acceleration bounded by tan(max_tilt) * (g + a_z)
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
        # yaw authority comes from differential rotor drag: never let it starve thrust or tilt
        torque[2] = np.clip(torque[2], -g.max_yaw_torque, g.max_yaw_torque)
        return max(thrust, 0.0), torque
