"""The simulated vehicle's MAVLink side, in the manner of PX4 SITL.

It owns the links, answers commands with honest COMMAND_ACKs, runs the parameter and
mission protocols, streams telemetry at requested rates, flies the PX4-style modes
(takeoff, loiter, mission, RTL, land, offboard) through any FlightModel, enforces a geofence
and sends camera frames over the image transmission protocol. Everything happens in `tick`,
called from the lock-step runner, so simulated time drives it all.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsFix, GpsModel
from sim.vehicle.model import FlightModel

from .images import frame_messages
from .mission import MissionItem, MissionStore
from .modes import px4_mode_name
from .params import ParamStore
from .telemetry import BUILDERS, DEFAULT_RATES, Snapshot
from .udp import UdpLink

M = mavlink
log = logging.getLogger(__name__)
FORCE_MAGIC = 21196
#: PX4 modes flown from RC sticks; no MANUAL_CONTROL is simulated, so they are refused
STICK_MODES = {"MANUAL", "ALTCTL", "POSCTL", "ACRO", "STABILIZED"}
FENCE_LOOKAHEAD_S = 1.5  # how far ahead a velocity setpoint is checked against the fence
REQUESTABLE = set(DEFAULT_RATES) | {M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE}


@dataclass
class Geofence:
    max_horizontal_m: float = 100.0
    max_altitude_m: float = 30.0

    def allows(self, ned: np.ndarray) -> bool:
        return bool(np.hypot(ned[0], ned[1]) <= self.max_horizontal_m and -ned[2] <= self.max_altitude_m)

    def clamp(self, ned: np.ndarray, margin_m: float = 1.0) -> np.ndarray:
        """The point nearest `ned` at least `margin_m` inside the fence."""
        out = np.asarray(ned, dtype=float).copy()
        r, r_max = float(np.hypot(out[0], out[1])), max(self.max_horizontal_m - margin_m, 0.0)
        if r > r_max:
            out[:2] *= r_max / r
        out[2] = max(out[2], -max(self.max_altitude_m - margin_m, 0.5))
        return out


@dataclass
class VehicleCounters:
    commands: int = 0
    denied: int = 0
    fence_rejections: int = 0
    frames_sent: int = 0
    handler_errors: list[str] = field(default_factory=list)  # messages that raised in a handler
    statustext: list[str] = field(default_factory=list)


class MavlinkVehicle:
    def __init__(
        self,
        model: FlightModel,
        links: list[UdpLink],
        home: HomePosition,
        gps: GpsModel,
        camera: Callable[[np.ndarray, float], np.ndarray] | None = None,
        system_id: int = 1,
        signing: bool = False,
    ) -> None:
        self.model, self.links, self.home, self.gps, self.camera = model, links, home, gps, camera
        self.sysid = system_id
        self.params = ParamStore(signing=signing)
        self.mission = MissionStore()
        self.mode = "AUTO.LOITER"
        self.rates = dict(DEFAULT_RATES)
        self._next_due = {k: 0.0 for k in self.rates}
        self.t = 0.0
        self.fix: GpsFix | None = None
        self.counters = VehicleCounters()
        self._target: np.ndarray | None = None  # NED hold/goto target
        self._offboard_t = -1e9
        self._velocity_control = False  # the model tracks a velocity, not a position
        self._fence_hold = False  # holding inside after a breach
        self._rtl_phase = 0
        self._wp_reached = -1
        self._pending_frames = 0
        self._next_frame_t = 0.0

    # -- helpers -------------------------------------------------------------------------
    @property
    def mav(self) -> mavlink.MAVLink:
        return self.links[0].mav

    def fence(self) -> Geofence:
        return Geofence(self.params["GF_MAX_HOR_DIST"], self.params["GF_MAX_VER_DIST"])

    def send(self, msg) -> None:
        for link in self.links:
            link.send(msg)

    def statustext(self, text: str, severity: int = M.MAV_SEVERITY_INFO) -> None:
        self.counters.statustext.append(text)
        self.send(self.mav.statustext_encode(severity, text[:50].encode()))

    def _ack(self, cmd: int, result: int, msg) -> None:
        if result != M.MAV_RESULT_ACCEPTED:
            self.counters.denied += 1
        self.send(self.mav.command_ack_encode(cmd, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))

    def _set_mode(self, mode: str) -> None:
        if mode != self.mode:
            self.mode = mode
            self._rtl_phase = 0
            if mode == "AUTO.LOITER":
                self._hold_here()

    def estimate(self) -> np.ndarray:
        """The autopilot's position estimate: truth plus the GPS error it cannot see (what an
        EKF fed by this GPS converges to). Targets are flown in this frame, as on a real drone."""
        return self.model.state.position_ned + self.gps.bias

    def _command_model(self, target_est: np.ndarray, yaw: float | None = None, speed: float | None = None) -> None:
        self._velocity_control = False
        self.model.set_position_target(np.asarray(target_est, float) - self.gps.bias, yaw=yaw, speed=speed)

    def _hold_here(self) -> None:
        s = self.model.state
        self._target = self.estimate()
        if s.armed and not s.landed:
            self._command_model(self._target, speed=self.params["MPC_XY_VEL_MAX"])

    def _goto(self, ned: np.ndarray, speed: float | None = None) -> bool:
        if not self.fence().allows(ned):
            self.counters.fence_rejections += 1
            self.statustext(f"Geofence: target {ned[0]:.0f},{ned[1]:.0f},{-ned[2]:.0f} m rejected", M.MAV_SEVERITY_WARNING)
            return False
        self._target = np.asarray(ned, dtype=float).copy()
        self._command_model(self._target, speed=speed or self.params["MPC_XY_CRUISE"])
        return True

    def _item_ned(self, item: MissionItem) -> np.ndarray:
        ned = self.home.geodetic_to_ned(item.x * 1e-7, item.y * 1e-7, self.home.alt_m)
        rel = item.z if item.frame in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) else item.z - self.home.alt_m
        return np.array([ned[0], ned[1], -rel])

    # -- the tick ------------------------------------------------------------------------
    def service(self) -> None:
        """Answer whatever has arrived, without advancing time (between physics ticks)."""
        for link in self.links:
            for msg in link.poll():
                try:
                    self.handle(msg)
                except Exception as e:  # a well-formed message with absurd content: drop it, fly on
                    self.counters.handler_errors.append(f"{msg.get_type()}: {type(e).__name__}: {e}")
                    log.exception("dropped %s after a handler error", msg.get_type())

    def tick(self, t: float) -> None:
        self.t = t
        self.service()
        s = self.model.state
        fix = self.gps.sample(t, s.position_ned, s.velocity_ned)
        if fix is not None:
            self.fix = fix
        self._fly()
        self._stream()
        self._mission_retry()

    def _fly(self) -> None:
        s = self.model.state
        if not s.armed:
            return
        if not s.landed and self._fence_breach():
            return
        if self.mode == "AUTO.TAKEOFF" and self._target is not None:
            if abs(self.estimate()[2] - self._target[2]) < 0.3:
                self._set_mode("AUTO.LOITER")
        elif self.mode == "AUTO.MISSION":
            self._fly_mission()
        elif self.mode == "AUTO.RTL":
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
        elif self.mode == "OFFBOARD" and self.t - self._offboard_t > self.params["COM_OF_LOSS_T"]:
            self.statustext("Offboard setpoints lost: holding position", M.MAV_SEVERITY_WARNING)
            self._set_mode("AUTO.LOITER")

    def _fence_breach(self) -> bool:
        """Hold inside the fence when the vehicle is outside it, or about to leave it under
        velocity control (targets are checked before they are flown; velocities cannot be)."""
        fence, p = self.fence(), self.estimate()
        ahead = p + self.model.state.velocity_ned * FENCE_LOOKAHEAD_S if self._velocity_control else p
        if fence.allows(p) and fence.allows(ahead):
            self._fence_hold = False
            return False
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
            self._set_mode("AUTO.LOITER")
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
            self._set_mode("AUTO.RTL")
            return
        goal = self._item_ned(item)
        if item.command == M.MAV_CMD_NAV_TAKEOFF:
            goal[:2] = self.estimate()[:2] if self._target is None else self._target[:2]
        if self._target is None or not np.allclose(self._target, goal):
            if not self._goto(goal):
                self._set_mode("AUTO.LOITER")
                return
        radius = item.params[1] if item.command == M.MAV_CMD_NAV_WAYPOINT and item.params[1] > 0 else self.params["NAV_ACC_RAD"]
        if np.linalg.norm(self.estimate() - goal) < max(radius, 0.3):
            self._advance(item)

    def _advance(self, item: MissionItem) -> None:
        self.send(self.mav.mission_item_reached_encode(item.seq))
        self.mission.current += 1
        self._send_mission_current()

    # -- telemetry -----------------------------------------------------------------------
    def _stream(self) -> None:
        for msg_id, hz in self.rates.items():
            if hz <= 0 or self.t + 1e-9 < self._next_due.get(msg_id, 0.0):
                continue
            self._next_due[msg_id] = self.t + 1.0 / hz
            self._send_message(msg_id)
        if self._pending_frames or (self.params["UAVS_CAM_RATE"] > 0 and self.t >= self._next_frame_t):
            self._send_frame()

    def snapshot(self) -> Snapshot:
        return Snapshot(self.t, self.model.state, self.estimate(), self.home, self.fix, self.mode, self.sysid)

    def _send_message(self, msg_id: int) -> bool:
        """Send one message now (stream tick or REQUEST_MESSAGE); False if there is none to send."""
        if msg_id == M.MAVLINK_MSG_ID_MISSION_CURRENT:
            self._send_mission_current()
            return True
        if msg_id == M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE:
            self._pending_frames += 1  # a camera frame goes out on the next tick
            return True
        build = BUILDERS.get(msg_id)
        msg = build(self.mav, self.snapshot()) if build is not None else None
        if msg is None:
            return False
        self.send(msg)
        return True

    def _send_mission_current(self) -> None:
        self.send(self.mav.mission_current_encode(self.mission.current, len(self.mission.items),
                                                  self._mission_state()))

    def _mission_state(self) -> int:
        if not self.mission.items:
            return M.MISSION_STATE_NO_MISSION
        if self.mission.current >= len(self.mission.items):
            return M.MISSION_STATE_COMPLETE
        return M.MISSION_STATE_ACTIVE if self.mode == "AUTO.MISSION" else M.MISSION_STATE_NOT_STARTED

    def _send_frame(self) -> None:
        if self.camera is None:
            self._pending_frames = 0
            return
        s = self.model.state
        frame = self.camera(s.position_ned, float(s.attitude_rpy[2]))
        for m in frame_messages(self.mav, frame):
            self.send(m)
        self.counters.frames_sent += 1
        self._pending_frames = max(0, self._pending_frames - 1)
        rate = self.params["UAVS_CAM_RATE"]
        self._next_frame_t = self.t + (1.0 / rate if rate > 0 else 0.0)

    # -- incoming ------------------------------------------------------------------------
    def handle(self, msg) -> None:
        kind = msg.get_type()
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.sysid):
            return
        # addressed to another component of this system (a camera, a gimbal): not ours to answer
        if getattr(msg, "target_component", None) not in (None, 0, M.MAV_COMP_ID_AUTOPILOT1):
            return
        handler = getattr(self, f"_on_{kind.lower()}", None)
        if handler is not None:
            handler(msg)

    def _on_command_long(self, msg) -> None:
        self._command(msg, msg.command, [msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7], False)

    def _on_command_int(self, msg) -> None:
        self._command(msg, msg.command, [msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z], True, msg.frame)

    def _command(self, msg, cmd: int, p: list[float], is_int: bool, frame: int = M.MAV_FRAME_GLOBAL) -> None:
        self.counters.commands += 1
        s = self.model.state
        R = M
        # MAVSDK and others send NaN for unused parameters: integers read them as 0
        q = [int(x) if math.isfinite(x) else 0 for x in p]
        if cmd == R.MAV_CMD_COMPONENT_ARM_DISARM:
            force = q[1] == FORCE_MAGIC
            if p[0] >= 0.5:
                if self.fix is None and not force:
                    self.statustext("Arming denied: no GPS fix", M.MAV_SEVERITY_CRITICAL)
                    return self._ack(cmd, R.MAV_RESULT_TEMPORARILY_REJECTED, msg)
                ok = self.model.arm()
                if ok and s.landed:
                    self._target = self.estimate()
                return self._ack(cmd, R.MAV_RESULT_ACCEPTED if ok else R.MAV_RESULT_DENIED, msg)
            ok = self.model.disarm(force=force)
            if not ok:
                self.statustext("Disarming denied: in air", M.MAV_SEVERITY_WARNING)
            return self._ack(cmd, R.MAV_RESULT_ACCEPTED if ok else R.MAV_RESULT_DENIED, msg)
        if cmd == R.MAV_CMD_DO_SET_MODE:
            name = px4_mode_name(q[1], q[2]) if q[0] & R.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED else None
            if name is None:
                return self._ack(cmd, R.MAV_RESULT_UNSUPPORTED, msg)
            if name in STICK_MODES:
                self.statustext(f"{name} needs manual control input, which this vehicle has not", M.MAV_SEVERITY_WARNING)
                return self._ack(cmd, R.MAV_RESULT_DENIED, msg)
            if name == "OFFBOARD" and self.t - self._offboard_t > self.params["COM_OF_LOSS_T"]:
                self.statustext("Offboard denied: stream setpoints first", M.MAV_SEVERITY_WARNING)
                return self._ack(cmd, R.MAV_RESULT_TEMPORARILY_REJECTED, msg)
            if name == "AUTO.MISSION" and not self.mission.items:
                return self._ack(cmd, R.MAV_RESULT_DENIED, msg)
            if name == "AUTO.RTL" and (not s.armed or s.landed):
                return self._ack(cmd, R.MAV_RESULT_TEMPORARILY_REJECTED, msg)
            if name == "AUTO.TAKEOFF":  # as PX4: the mode itself climbs to MIS_TAKEOFF_ALT
                return self._ack(cmd, self._takeoff(math.nan), msg)
            return self._enter(msg, cmd, name)
        if cmd == R.MAV_CMD_NAV_TAKEOFF:
            return self._ack(cmd, self._takeoff(p[6]), msg)
        if cmd == R.MAV_CMD_NAV_LAND:
            self.mode = "AUTO.LAND"
            self.model.land()
            return self._ack(cmd, R.MAV_RESULT_ACCEPTED, msg)
        if cmd == R.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            if not s.armed or s.landed:
                return self._ack(cmd, R.MAV_RESULT_TEMPORARILY_REJECTED, msg)
            return self._enter(msg, cmd, "AUTO.RTL")
        if cmd == R.MAV_CMD_MISSION_START:
            if not self.mission.items:
                return self._ack(cmd, R.MAV_RESULT_DENIED, msg)
            first = max(q[0], 0)
            self.mission.current = min(first, len(self.mission.items) - 1)
            return self._enter(msg, cmd, "AUTO.MISSION")
        if cmd == R.MAV_CMD_DO_REPOSITION:
            if not s.armed or s.landed:
                return self._ack(cmd, R.MAV_RESULT_TEMPORARILY_REJECTED, msg)
            lat = p[4] * 1e-7 if is_int else p[4]
            lon = p[5] * 1e-7 if is_int else p[5]
            ned = self.estimate()
            if math.isfinite(lat) and math.isfinite(lon):
                ned[:2] = self.home.geodetic_to_ned(lat, lon, self.home.alt_m)[:2]
            if math.isfinite(p[6]):
                rel = p[6] if frame in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) else p[6] - self.home.alt_m
                ned[2] = -rel
            speed = p[0] if math.isfinite(p[0]) and p[0] > 0 else None
            if not self._goto(ned, speed):
                return self._ack(cmd, R.MAV_RESULT_DENIED, msg)
            self.mode = "AUTO.LOITER"
            return self._ack(cmd, R.MAV_RESULT_ACCEPTED, msg)
        if cmd == R.MAV_CMD_DO_CHANGE_SPEED:
            ok, why = self.params.set("MPC_XY_CRUISE", float(p[1]))
            if ok and self._target is not None and s.armed and not s.landed:
                self._command_model(self._target, speed=float(p[1]))
            return self._ack(cmd, R.MAV_RESULT_ACCEPTED if ok else R.MAV_RESULT_DENIED, msg)
        if cmd == R.MAV_CMD_SET_MESSAGE_INTERVAL:
            msg_id, interval = q[0], p[1]
            if not (math.isfinite(p[0]) and math.isfinite(interval)):
                return self._ack(cmd, R.MAV_RESULT_DENIED, msg)  # NaN is no message id, and no interval
            if msg_id not in DEFAULT_RATES and msg_id != M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                return self._ack(cmd, R.MAV_RESULT_UNSUPPORTED, msg)
            self.rates[msg_id] = DEFAULT_RATES.get(msg_id, 0.0) if interval == 0 else (0.0 if interval < 0 else 1e6 / interval)
            self._next_due[msg_id] = self.t
            return self._ack(cmd, R.MAV_RESULT_ACCEPTED, msg)
        if cmd == R.MAV_CMD_REQUEST_MESSAGE:
            # the ACK first, then the message, as the command protocol describes
            if not math.isfinite(p[0]):
                return self._ack(cmd, R.MAV_RESULT_DENIED, msg)
            if q[0] not in REQUESTABLE or (q[0] == M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE and self.camera is None):
                return self._ack(cmd, R.MAV_RESULT_UNSUPPORTED, msg)
            if q[0] == M.MAVLINK_MSG_ID_GPS_RAW_INT and self.fix is None:
                return self._ack(cmd, R.MAV_RESULT_TEMPORARILY_REJECTED, msg)
            self._ack(cmd, R.MAV_RESULT_ACCEPTED, msg)
            self._send_message(q[0])
            return None
        if cmd == R.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self._ack(cmd, R.MAV_RESULT_ACCEPTED, msg)
            self._send_message(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
            return None
        if cmd == R.MAV_CMD_GET_HOME_POSITION:
            self._ack(cmd, R.MAV_RESULT_ACCEPTED, msg)
            self._send_message(M.MAVLINK_MSG_ID_HOME_POSITION)
            return None
        return self._ack(cmd, R.MAV_RESULT_UNSUPPORTED, msg)

    def _takeoff(self, alt_amsl: float) -> int:
        """Climb over the current position to alt_amsl (NaN: MIS_TAKEOFF_ALT); a MAV_RESULT."""
        if not self.model.state.armed:
            return M.MAV_RESULT_TEMPORARILY_REJECTED
        rel = alt_amsl - self.home.alt_m if math.isfinite(alt_amsl) else self.params["MIS_TAKEOFF_ALT"]
        if rel <= 0.3:
            rel = self.params["MIS_TAKEOFF_ALT"]
        est = self.estimate()
        if not self._goto(np.array([est[0], est[1], -rel]), speed=self.params["MPC_XY_CRUISE"]):
            return M.MAV_RESULT_DENIED
        self.mode = "AUTO.TAKEOFF"
        return M.MAV_RESULT_ACCEPTED

    def _enter(self, msg, cmd: int, name: str) -> None:
        self._set_mode(name)
        if name == "AUTO.LAND":
            self.model.land()
        self._ack(cmd, M.MAV_RESULT_ACCEPTED, msg)

    def _on_data_transmission_handshake(self, msg) -> None:
        """The image protocol's own request: a receiver's handshake asks for one frame (we send
        PNG whatever type it names, and say so in our handshake)."""
        if self.camera is not None:
            self._pending_frames += 1

    def _on_set_mode(self, msg) -> None:
        """The deprecated SET_MODE message: obeyed like DO_SET_MODE, without the ACK."""
        name = px4_mode_name((msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF)
        if name is not None and name not in STICK_MODES and name != "OFFBOARD":
            self._set_mode(name)

    def _on_set_position_target_local_ned(self, msg) -> None:
        self._offboard(msg, np.array([msg.x, msg.y, msg.z]), np.array([msg.vx, msg.vy, msg.vz]), msg.yaw)

    def _on_set_position_target_global_int(self, msg) -> None:
        ned = self.home.geodetic_to_ned(msg.lat_int * 1e-7, msg.lon_int * 1e-7, self.home.alt_m)
        rel = msg.alt if msg.coordinate_frame in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) else msg.alt - self.home.alt_m
        self._offboard(msg, np.array([ned[0], ned[1], -rel]), np.array([msg.vx, msg.vy, msg.vz]), msg.yaw)

    def _offboard(self, msg, pos: np.ndarray, vel: np.ndarray, yaw: float) -> None:
        mask = msg.type_mask
        use_pos = not (mask & M.POSITION_TARGET_TYPEMASK_X_IGNORE)
        self._offboard_t = self.t
        if self.mode != "OFFBOARD":
            return  # PX4 accepts the stream before the switch, and acts on it only in OFFBOARD
        if use_pos:
            if not self.fence().allows(pos):
                self.counters.fence_rejections += 1
                self.statustext("Geofence: offboard setpoint rejected", M.MAV_SEVERITY_WARNING)
                return
            yaw_v = None if mask & M.POSITION_TARGET_TYPEMASK_YAW_IGNORE else yaw
            self._target = pos
            self._command_model(pos, yaw=yaw_v, speed=self.params["MPC_XY_VEL_MAX"])
        elif not (mask & M.POSITION_TARGET_TYPEMASK_VX_IGNORE):
            self._velocity_control = True
            self.model.set_velocity_target(vel)

    # -- parameters ----------------------------------------------------------------------
    def _param_value(self, name: str) -> None:
        self.send(self.mav.param_value_encode(name.encode(), self.params[name], M.MAV_PARAM_TYPE_REAL32,
                                              len(self.params.names), self.params.index(name)))

    def _on_param_request_list(self, msg) -> None:
        for name in self.params.names:
            self._param_value(name)

    def _on_param_request_read(self, msg) -> None:
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        name = name.rstrip("\0")
        if msg.param_index >= 0 and msg.param_index < len(self.params.names):
            name = self.params.names[msg.param_index]
        if name in self.params.params:
            self._param_value(name)

    def _on_param_set(self, msg) -> None:
        name = (msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()).rstrip("\0")
        ok, why = self.params.set(name, float(msg.param_value))
        if not ok:
            self.statustext(f"Param rejected: {why}", M.MAV_SEVERITY_WARNING)
        if name in self.params.params:
            self._param_value(name)

    # -- missions ------------------------------------------------------------------------
    def _mission_ack(self, msg, result: int, mission_type: int = 0) -> None:
        self.send(self.mav.mission_ack_encode(msg.get_srcSystem(), msg.get_srcComponent(), result, mission_type))

    def _request_item(self, seq: int) -> None:
        sysid, comp = self.mission.partner
        self.send(self.mav.mission_request_int_encode(sysid, comp, seq, 0))
        self.mission.last_request_t = self.t

    def _on_mission_count(self, msg) -> None:
        mtype = getattr(msg, "mission_type", 0)
        if mtype != M.MAV_MISSION_TYPE_MISSION:
            return self._mission_ack(msg, M.MAV_MISSION_UNSUPPORTED, mtype)
        if self.mode == "AUTO.MISSION" and self.model.state.armed:
            return self._mission_ack(msg, M.MAV_MISSION_DENIED)
        self.mission.partner = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.count == 0:
            self.mission.items, self.mission.current = [], 0
            return self._mission_ack(msg, M.MAV_MISSION_ACCEPTED)
        self.mission.incoming = [None] * msg.count
        self.mission.retries = 0
        self._request_item(0)
        return None

    def _on_mission_item_int(self, msg) -> None:
        inc = self.mission.incoming
        if inc is None or getattr(msg, "mission_type", 0) != 0:
            return
        if msg.seq >= len(inc):
            self.mission.incoming = None
            return self._mission_ack(msg, M.MAV_MISSION_INVALID_SEQUENCE)
        item = MissionItem.from_msg(msg)
        result = self.mission.validate(item, lambda it: self.fence().allows(self._item_ned(it)))
        if result != M.MAV_MISSION_ACCEPTED:
            self.mission.incoming = None
            if result == M.MAV_MISSION_DENIED:
                self.counters.fence_rejections += 1
                self.statustext(f"Mission item {item.seq} outside the geofence", M.MAV_SEVERITY_WARNING)
            return self._mission_ack(msg, result)
        inc[msg.seq] = item
        missing = [i for i, x in enumerate(inc) if x is None]
        if missing:
            self.mission.retries = 0
            return self._request_item(missing[0])
        self.mission.items = [x for x in inc if x is not None]
        self.mission.current = 0
        self.mission.incoming = None
        self._mission_ack(msg, M.MAV_MISSION_ACCEPTED)
        self._send_mission_current()
        return None

    _on_mission_item = _on_mission_item_int

    def _mission_retry(self) -> None:
        inc = self.mission.incoming
        if inc is None or self.t - self.mission.last_request_t < 0.5:
            return
        self.mission.retries += 1
        if self.mission.retries > 5:
            self.mission.incoming = None
            self.statustext("Mission upload timed out", M.MAV_SEVERITY_WARNING)
            return
        missing = [i for i, x in enumerate(inc) if x is None]
        self._request_item(missing[0])

    def _on_mission_request_list(self, msg) -> None:
        mtype = getattr(msg, "mission_type", 0)
        n = len(self.mission.items) if mtype == M.MAV_MISSION_TYPE_MISSION else 0
        self.send(self.mav.mission_count_encode(msg.get_srcSystem(), msg.get_srcComponent(), n, mtype))

    def _on_mission_request_int(self, msg) -> None:
        if msg.seq >= len(self.mission.items) or getattr(msg, "mission_type", 0) != 0:
            return self._mission_ack(msg, M.MAV_MISSION_INVALID_SEQUENCE)
        it = self.mission.items[msg.seq]
        self.send(self.mav.mission_item_int_encode(
            msg.get_srcSystem(), msg.get_srcComponent(), it.seq, it.frame, it.command,
            int(it.seq == self.mission.current), it.autocontinue, *it.params, it.x, it.y, it.z, 0))
        return None

    _on_mission_request = _on_mission_request_int

    def _on_mission_clear_all(self, msg) -> None:
        if getattr(msg, "mission_type", 0) in (M.MAV_MISSION_TYPE_MISSION, M.MAV_MISSION_TYPE_ALL):
            self.mission.items, self.mission.current = [], 0
            if self.mode == "AUTO.MISSION":
                self._set_mode("AUTO.LOITER")
        self._mission_ack(msg, M.MAV_MISSION_ACCEPTED, getattr(msg, "mission_type", 0))

    def _on_mission_set_current(self, msg) -> None:
        if 0 <= msg.seq < len(self.mission.items):
            self.mission.current = msg.seq
            self._target = None
        self._send_mission_current()

    def _on_mission_ack(self, msg) -> None:
        pass  # the end of a download; nothing to do
