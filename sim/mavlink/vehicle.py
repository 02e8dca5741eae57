"""The simulated vehicle's MAVLink side, in the manner of PX4 SITL.

It owns the links, dispatches what arrives (commands.py, mission.py, params.py), streams
telemetry at requested rates (telemetry.py), flies the PX4-style modes (takeoff, loiter,
mission, RTL, land, offboard) through any FlightModel, enforces a geofence and sends camera
frames over the image transmission protocol. The flying runs in `tick`, on simulated time;
timers that wait on a remote client (offboard setpoint loss, mission re-requests) run on
wall-clock time, because the client does.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsFix, GpsModel
from sim.vehicle.model import FlightModel

from .commands import ATTITUDE_MODES, RELATIVE_FRAMES, Command, execute
from .images import frame_messages
from .mission import MissionItem, MissionProtocol, MissionStore
from .modes import px4_mode_name
from .params import ParamStore, param_replies
from .telemetry import BUILDERS, DEFAULT_RATES, Snapshot
from .udp import UdpLink

M = mavlink
#: telemetry streams run at most this many times their rate in wall-clock time
MAX_STREAM_SPEEDUP = 50.0
log = logging.getLogger(__name__)
FENCE_LOOKAHEAD_S = 1.5  # how far ahead a velocity setpoint is checked against the fence
STICK_DEADBAND = 0.05  # of full deflection; inside it POSCTL holds position
#: SET_POSITION_TARGET_LOCAL_NED frames flown: positions absolute, or offsets from here
LOCAL_FRAMES = frozenset({M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_OFFSET_NED, M.MAV_FRAME_BODY_OFFSET_NED,
                          M.MAV_FRAME_BODY_FRD})


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
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.model, self.links, self.home, self.gps, self.camera = model, links, home, gps, camera
        self.sysid = system_id
        self.clock = clock  # wall clock, for timers that wait on a client
        self._next_wall: dict[int, float] = {}
        self.params = ParamStore(signing=signing)
        self.mission = MissionStore()
        self.missions = MissionProtocol(self, self.mission, clock)
        self.mode = "AUTO.LOITER"
        self.rates = dict(DEFAULT_RATES)
        self._next_due = {k: 0.0 for k in self.rates}
        self.t = 0.0
        self.fix: GpsFix | None = None
        self.counters = VehicleCounters()
        self._target: np.ndarray | None = None  # NED hold/goto target (estimate frame)
        self._offboard_wall_t = -1e9  # when the last offboard setpoint arrived
        self._manual_wall_t = -1e9  # when the last MANUAL_CONTROL arrived
        self._sticks = np.zeros(4)  # forward, right, up, yaw rate: each in [-1, 1]
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

    def send(self, msg: mavlink.MAVLink_message) -> None:
        for link in self.links:
            link.send(msg)

    def statustext(self, text: str, severity: int = M.MAV_SEVERITY_INFO) -> None:
        self.counters.statustext.append(text)
        self.send(self.mav.statustext_encode(severity, text[:50].encode()))

    def estimate(self) -> np.ndarray:
        """The autopilot's position estimate: truth plus the GPS error it cannot see (what an
        EKF fed by this GPS converges to). Targets are flown in this frame, as on a real drone."""
        return self.model.state.position_ned + self.gps.bias

    def set_mode(self, mode: str) -> None:
        if mode != self.mode:
            self.mode = mode
            self._rtl_phase = 0
            if mode in ("AUTO.LOITER", "POSCTL"):
                self._hold_here()
        if mode == "AUTO.LAND":
            self.model.land()

    def arm(self) -> bool:
        ok = self.model.arm()
        if ok and self.model.state.landed:
            self._target = self.estimate()
        return ok

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

    def offboard_fresh(self) -> bool:
        return self.clock() - self._offboard_wall_t <= self.params["COM_OF_LOSS_T"]

    def manual_fresh(self) -> bool:
        return self.clock() - self._manual_wall_t <= self.params["COM_RC_LOSS_T"]

    def set_rate(self, msg_id: int, hz: float) -> None:
        self.rates[msg_id] = hz
        self._next_due[msg_id] = self.t

    def _command_model(self, target_est: np.ndarray, yaw: float | None = None, speed: float | None = None) -> None:
        self._velocity_control = False
        self.model.set_position_target(np.asarray(target_est, float) - self.gps.bias, yaw=yaw, speed=speed)

    def _hold_here(self) -> None:
        s = self.model.state
        self._target = self.estimate()
        if s.armed and not s.landed:
            self._command_model(self._target, speed=self.params["MPC_XY_VEL_MAX"])

    def _item_ned(self, item: MissionItem) -> np.ndarray:
        ned = self.home.geodetic_to_ned(item.x * 1e-7, item.y * 1e-7, self.home.alt_m)
        rel = item.z if item.frame in RELATIVE_FRAMES else item.z - self.home.alt_m
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
        self.missions.poll()

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
        elif self.mode == "OFFBOARD" and not self.offboard_fresh():
            self.statustext("Offboard setpoints lost: holding position", M.MAV_SEVERITY_WARNING)
            self.set_mode("AUTO.LOITER")
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

    # -- the mission protocol's host -------------------------------------------------------
    def mission_item_allowed(self, item: MissionItem) -> bool:
        if self.fence().allows(self._item_ned(item)):
            return True
        self.counters.fence_rejections += 1
        self.statustext(f"Mission item {item.seq} outside the geofence", M.MAV_SEVERITY_WARNING)
        return False

    def mission_running(self) -> bool:
        return self.mode == "AUTO.MISSION" and self.model.state.armed

    def mission_changed(self, cleared: bool) -> None:
        if self.mode != "AUTO.MISSION":
            return
        if cleared:
            self.set_mode("AUTO.LOITER")
        else:
            self._target = None  # fly to the new current item

    def send_mission_current(self) -> None:
        self.send(self.mav.mission_current_encode(self.mission.current, len(self.mission.items),
                                                  self._mission_state()))

    def _mission_state(self) -> int:
        if not self.mission.items:
            return M.MISSION_STATE_NO_MISSION
        if self.mission.current >= len(self.mission.items):
            return M.MISSION_STATE_COMPLETE
        return M.MISSION_STATE_ACTIVE if self.mode == "AUTO.MISSION" else M.MISSION_STATE_NOT_STARTED

    # -- telemetry -----------------------------------------------------------------------
    def _stream(self) -> None:
        now = self.clock()
        for msg_id, hz in self.rates.items():
            if hz <= 0 or self.t + 1e-9 < self._next_due.get(msg_id, 0.0):
                continue
            # due in simulated time; but never more than MAX_STREAM_SPEEDUP x the rate in wall time,
            # so a simulation racing ahead (speedup 0) cannot flood a client's receive buffer
            if now < self._next_wall.get(msg_id, 0.0):
                continue
            self._next_due[msg_id] = self.t + 1.0 / hz
            self._next_wall[msg_id] = now + 1.0 / (hz * MAX_STREAM_SPEEDUP)
            self.send_message(msg_id)
        if self._pending_frames or (self.params["UAVS_CAM_RATE"] > 0 and self.t >= self._next_frame_t):
            self._send_frame()

    def snapshot(self) -> Snapshot:
        return Snapshot(self.t, self.model.state, self.estimate(), self.home, self.fix, self.mode, self.sysid)

    def send_message(self, msg_id: int) -> bool:
        """Send one message now (stream tick or REQUEST_MESSAGE); False if there is none to send."""
        if msg_id == M.MAVLINK_MSG_ID_MISSION_CURRENT:
            self.send_mission_current()
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
    def handle(self, msg: mavlink.MAVLink_message) -> None:
        kind = msg.get_type()
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.sysid):
            return
        # addressed to another component of this system (a camera, a gimbal): not ours to answer
        if getattr(msg, "target_component", None) not in (None, 0, M.MAV_COMP_ID_AUTOPILOT1):
            return
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._on_command(msg)
        elif kind in MissionProtocol.HANDLES:
            self.missions.handle(msg)
        elif kind in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            replies, refused = param_replies(self.mav, self.params, msg)
            if refused:
                self.statustext(f"Param rejected: {refused}", M.MAV_SEVERITY_WARNING)
            for reply in replies:
                self.send(reply)
        elif kind in ("SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT"):
            self._on_setpoint(msg)
        elif kind == "DATA_TRANSMISSION_HANDSHAKE":
            # the image protocol's own request: a receiver's handshake asks for one frame (we
            # send PNG whatever type it names, and say so in our handshake)
            if self.camera is not None:
                self._pending_frames += 1
        elif kind == "TIMESYNC" and msg.tc1 == 0:  # a request: answer with our clock (simulated ns)
            self.send(self.mav.timesync_encode(max(int(self.t * 1e9), 1), msg.ts1))
        elif kind == "MANUAL_CONTROL":
            self._on_manual_control(msg)
        elif kind == "SET_MODE":  # deprecated: obeyed like DO_SET_MODE, without an ACK
            name = px4_mode_name((msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF)
            if name is not None and name not in ATTITUDE_MODES and name != "OFFBOARD" and (
                    name != "POSCTL" or self.manual_fresh()):
                self.set_mode(name)

    def _on_manual_control(self, msg: mavlink.MAVLink_message) -> None:
        """Sticks as QGroundControl's joystick sends them: x forward, y right, r yaw in
        [-1000, 1000], z throttle in [0, 1000] with 500 centred."""
        if msg.target not in (0, self.sysid):
            return
        sticks = np.array([msg.x, msg.y, msg.z - 500.0, msg.r], dtype=float) / np.array([1000, 1000, 500, 1000])
        self._sticks = np.clip(sticks, -1.0, 1.0)
        self._manual_wall_t = self.clock()

    def _on_command(self, msg: mavlink.MAVLink_message) -> None:
        self.counters.commands += 1
        cmd = Command.from_msg(msg)
        result, then = execute(self, cmd)
        if result != M.MAV_RESULT_ACCEPTED:
            self.counters.denied += 1
        self.send(self.mav.command_ack_encode(cmd.id, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))
        if then is not None:
            then()

    def _on_setpoint(self, msg: mavlink.MAVLink_message) -> None:
        """OFFBOARD setpoints: accepted (and timed) in any mode, flown only in OFFBOARD, as PX4."""
        self._offboard_wall_t = self.clock()
        if self.mode != "OFFBOARD":
            return
        mask = msg.type_mask
        vel = np.array([msg.vx, msg.vy, msg.vz], dtype=float)
        yaw = None if mask & M.POSITION_TARGET_TYPEMASK_YAW_IGNORE or not math.isfinite(msg.yaw) else float(msg.yaw)
        if msg.get_type() == "SET_POSITION_TARGET_GLOBAL_INT":
            rel = msg.alt if msg.coordinate_frame in RELATIVE_FRAMES else msg.alt - self.home.alt_m
            ned = self.home.geodetic_to_ned(msg.lat_int * 1e-7, msg.lon_int * 1e-7, self.home.alt_m)
            pos = np.array([ned[0], ned[1], -rel])
        else:
            if msg.coordinate_frame not in LOCAL_FRAMES:
                self.statustext(f"Setpoint frame {msg.coordinate_frame} not supported", M.MAV_SEVERITY_WARNING)
                return
            pos = np.array([msg.x, msg.y, msg.z], dtype=float)
            if msg.coordinate_frame in (M.MAV_FRAME_BODY_OFFSET_NED, M.MAV_FRAME_BODY_FRD):
                c, s = math.cos(self.model.state.attitude_rpy[2]), math.sin(self.model.state.attitude_rpy[2])
                rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                pos, vel = rot @ pos, rot @ vel
            if msg.coordinate_frame != M.MAV_FRAME_LOCAL_NED:
                pos = pos + self.estimate()
        if not mask & M.POSITION_TARGET_TYPEMASK_X_IGNORE:
            if not self.fence().allows(pos):  # NaN is outside every fence
                self.counters.fence_rejections += 1
                self.statustext("Geofence: offboard setpoint rejected", M.MAV_SEVERITY_WARNING)
                return
            self._target = pos
            self._command_model(pos, yaw=yaw, speed=self.params["MPC_XY_VEL_MAX"])
        elif not mask & M.POSITION_TARGET_TYPEMASK_VX_IGNORE:
            if not np.all(np.isfinite(vel)):
                return
            self._velocity_control = True
            self.model.set_velocity_target(vel)
