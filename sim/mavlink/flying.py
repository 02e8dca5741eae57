"""How the vehicle flies its PX4-style modes (takeoff, loiter, mission, RTL, land, offboard,
position), on simulated time, and holds inside the geofence. A mixin of MavlinkVehicle: it
uses the vehicle's model, params, mission store and statustext."""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from .commands import RELATIVE_FRAMES
from .mission import MissionItem

M = mavlink
FENCE_LOOKAHEAD_S = 1.5  # how far ahead a velocity setpoint is checked against the fence
STICK_DEADBAND = 0.05  # of full deflection; inside it POSCTL holds position


class Flying:
    def takeoff(self, alt_amsl: float) -> int:
        """Climb over the current position to alt_amsl (NaN: MIS_TAKEOFF_ALT); a MAV_RESULT."""
        if not self.model.state.armed:
            return M.MAV_RESULT_TEMPORARILY_REJECTED
        rel = alt_amsl - self.home.alt_m if math.isfinite(alt_amsl) else self.params["MIS_TAKEOFF_ALT"]
        if rel <= 0.3:
            rel = self.params["MIS_TAKEOFF_ALT"]
        est = self.estimate()
        if not self.goto(np.array([est[0], est[1], -rel]), speed=self.params["MPC_XY_CRUISE"]):
            return M.MAV_RESULT_DENIED
        self.mode = "AUTO.TAKEOFF"
        return M.MAV_RESULT_ACCEPTED

    def goto(self, ned: np.ndarray, speed: float | None = None) -> bool:
        """Fly to an estimate-frame NED point, unless the geofence forbids it (then say so)."""
        if not self.fence().allows(ned):
            self.counters.fence_rejections += 1
            self.statustext(f"Geofence: target {ned[0]:.0f},{ned[1]:.0f},{-ned[2]:.0f} m rejected", M.MAV_SEVERITY_WARNING)
            return False
        self._target = np.asarray(ned, dtype=float).copy()
        self._command_model(self._target, speed=speed or self.params["MPC_XY_CRUISE"])
        return True

    def retarget(self, speed: float) -> None:
        """Fly on to the current target at a new speed."""
        s = self.model.state
        if self._target is not None and s.armed and not s.landed and not self._velocity_control:
            self._command_model(self._target, speed=speed)

    def _command_model(self, target_est: np.ndarray, yaw: float | None = None, speed: float | None = None) -> None:
        self._velocity_control = False
        self.model.set_position_target(np.asarray(target_est, float) - self.gps.estimate_error, yaw=yaw, speed=speed)

    def _follow_estimate(self) -> None:
        """A new GPS fix moved the estimate: the position controller tracks the OFFBOARD
        setpoint in the estimate frame on every fix, as an autopilot's does, not only when the
        next setpoint message happens to arrive (which would tie the true path to wall-clock
        message timing and make flights irreproducible)."""
        s = self.model.state
        if (self.mode in self.dialect.tracking_modes and self._target is not None and not self._velocity_control
                and s.armed and not s.landed):
            self._command_model(self._target, speed=self.params["MPC_XY_VEL_MAX"])

    def _hold_here(self) -> None:
        s = self.model.state
        self._target = self.estimate()
        if s.armed and not s.landed:
            self._command_model(self._target, speed=self.params["MPC_XY_VEL_MAX"])

    def _item_ned(self, item: MissionItem) -> np.ndarray:
        ned = self.home.geodetic_to_ned(item.x * 1e-7, item.y * 1e-7, self.home.alt_m)
        rel = item.z if item.frame in RELATIVE_FRAMES else item.z - self.home.alt_m
        return np.array([ned[0], ned[1], -rel])

    def _fly(self) -> None:
        s = self.model.state
        if not s.armed:
            return
        if not s.landed and self._fence_breach():
            return
        if self.mode == "AUTO.TAKEOFF" and self._target is not None:
            if abs(self.estimate()[2] - self._target[2]) < 0.3:
                self.set_mode("AUTO.LOITER")
        elif self.mode == "AUTO.MISSION":
            self._fly_mission()
        elif self.mode == "AUTO.RTL":
            self._fly_rtl()
        elif self.mode == "POSCTL":
            self._fly_sticks()

    def _fly_sticks(self) -> None:
        """PX4's position mode: sticks command horizontal velocity (body-aligned) and climb
        rate; centred sticks hold position; losing the sticks holds (PX4's RC-loss hold)."""
        if not self.manual_fresh():
            self.statustext("Manual control lost: holding position", M.MAV_SEVERITY_WARNING)
            self.set_mode("AUTO.LOITER")
            return
        fwd, right, up, _ = np.where(np.abs(self._sticks) < STICK_DEADBAND, 0.0, self._sticks)
        if fwd == right == up == 0.0:  # brake, then hold where it stopped (as PX4 does)
            if self._velocity_control and np.linalg.norm(self.model.state.velocity_ned) > 0.3:
                self.model.set_velocity_target(np.zeros(3))
            elif self._velocity_control or self._target is None:
                self._hold_here()
            return
        yaw = float(self.model.state.attitude_rpy[2])
        vmax = self.params["MPC_XY_VEL_MAX"]
        vel = np.array([(fwd * math.cos(yaw) - right * math.sin(yaw)) * vmax,
                        (fwd * math.sin(yaw) + right * math.cos(yaw)) * vmax,
                        -up * self.params["MPC_Z_VEL_MAX_UP"]])
        self._velocity_control = True
        self.model.set_velocity_target(vel, yaw_rate=float(self._sticks[3]))

    def _fly_rtl(self) -> None:
        """Climb to RTL_RETURN_ALT (if lower), fly home, land: PX4's RTL without the loiter."""
        alt = -self.params["RTL_RETURN_ALT"]
        p = self.estimate()
        if self._rtl_phase == 0:
            self._command_model(np.array([p[0], p[1], min(p[2], alt)]))
            self._rtl_phase = 1
        elif self._rtl_phase == 1 and p[2] <= min(p[2], alt) + 0.3:
            self._command_model(np.array([0.0, 0.0, min(p[2], alt)]), speed=self.params["MPC_XY_CRUISE"])
            self._rtl_phase = 2
        elif self._rtl_phase == 2 and np.hypot(p[0], p[1]) < self.params["NAV_ACC_RAD"]:
            self.model.land()
            self._rtl_phase = 3

    def _fence_breach(self) -> bool:
        """Hold inside the fence when the vehicle is outside it, or about to leave it under
        velocity control (targets are checked before they are flown; velocities cannot be)."""
        p = self.estimate()
        # every tick of every vehicle: the fence's test (Geofence.allows) in plain floats
        h, v = self.params["GF_MAX_HOR_DIST"], self.params["GF_MAX_VER_DIST"]
        x, y, z = p.tolist()
        inside = math.hypot(x, y) <= h and -z <= v
        if inside and self._velocity_control:
            x, y, z = (p + self.model.state.velocity_ned * FENCE_LOOKAHEAD_S).tolist()
            inside = math.hypot(x, y) <= h and -z <= v
        if inside:
            self._fence_hold = False
            return False
        fence = self.fence()
        if self._fence_hold and not self._velocity_control:
            return True  # already on the way back in
        self._fence_hold = True
        self.counters.fence_rejections += 1
        self.statustext("Geofence breach: holding inside", M.MAV_SEVERITY_CRITICAL)
        self.mode = "AUTO.LOITER"
        self._target = fence.clamp(p)
        self._command_model(self._target, speed=self.params["MPC_XY_CRUISE"])
        return True

    def _fly_mission(self) -> None:
        items = self.mission.items
        s = self.model.state
        if self.mission.current >= len(items):
            self.set_mode("AUTO.LOITER")
            return
        item = items[self.mission.current]
        if item.command == M.MAV_CMD_DO_CHANGE_SPEED:
            if item.params[1] > 0:
                self.params.set("MPC_XY_CRUISE", float(item.params[1]))
            self._advance(item)
            return
        if item.command == M.MAV_CMD_NAV_LAND:
            if self._wp_reached != item.seq:
                self._wp_reached = item.seq
                self.model.land()
            if not s.armed or s.landed:
                self._advance(item)
            return
        if item.command == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            self._advance(item)
            self.set_mode("AUTO.RTL")
            return
        goal = self._item_ned(item)
        if item.command == M.MAV_CMD_NAV_TAKEOFF:
            goal[:2] = self.estimate()[:2] if self._target is None else self._target[:2]
        if self._target is None or not np.allclose(self._target, goal):
            if not self.goto(goal):
                self.set_mode("AUTO.LOITER")
                return
        radius = item.params[1] if item.command == M.MAV_CMD_NAV_WAYPOINT and item.params[1] > 0 else self.params["NAV_ACC_RAD"]
        if np.linalg.norm(self.estimate() - goal) < max(radius, 0.3):
            self._advance(item)

    def _advance(self, item: MissionItem) -> None:
        self.send(self.mav.mission_item_reached_encode(item.seq))
        self.mission.current += 1
        self.send_mission_current()
