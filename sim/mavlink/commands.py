"""COMMAND_LONG and COMMAND_INT as PX4 answers them: one function per command, each returning the MAV_RESULT the
COMMAND_ACK carries (honestly: ACCEPTED only for what is done, DENIED for what will not be,
TEMPORARILY_REJECTED for what could be later, UNSUPPORTED for the rest) and, where the
command asks for a message, what to send after the ACK, as the command protocol orders."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

from .host import Host
from .modes import px4_mode_name
from .telemetry import DEFAULT_RATES

M = mavlink
FORCE_MAGIC = 21196  # param 2 of ARM_DISARM: arm/disarm regardless of checks
#: PX4 stick modes that command attitude or thrust: the FlightModel contract has no such
#: interface, so they are refused. POSCTL (sticks command velocity) is flown, given sticks.
ATTITUDE_MODES = frozenset({"MANUAL", "ALTCTL", "ACRO", "STABILIZED"})
REQUESTABLE = frozenset(DEFAULT_RATES) | {M.MAVLINK_MSG_ID_AUTOPILOT_VERSION}
HEARTBEAT_MAX_PERIOD_S = 1.0  # a HEARTBEAT interval may not be set longer (MAVLink: 1 Hz nominal)
MAX_STREAM_HZ = 100.0  # SET_MESSAGE_INTERVAL asking for more gets this
RELATIVE_FRAMES = frozenset({M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})


@dataclass(frozen=True)
class Command:
    """One command, whichever message carried it: params 1-7 (COMMAND_INT's x, y as sent)."""

    id: int
    p: tuple[float, float, float, float, float, float, float]
    is_int: bool = False
    frame: int = M.MAV_FRAME_GLOBAL

    @classmethod
    def from_msg(cls, msg: mavlink.MAVLink_message) -> Command:
        if msg.get_type() == "COMMAND_INT":
            return cls(msg.command, (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y),
                                     msg.z), True, msg.frame)
        return cls(msg.command, (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6,
                                 msg.param7))

    def i(self, k: int) -> int:
        """Param k+1 as an integer; MAVSDK and others send NaN for unused ones: read as 0."""
        x = self.p[k]
        return int(x) if math.isfinite(x) else 0

    def lat_lon(self) -> tuple[float, float]:
        scale = 1e-7 if self.is_int else 1.0
        return self.p[4] * scale, self.p[5] * scale

    def rel_alt(self, home_alt_m: float) -> float:
        """Param 7 as metres above home, whatever the frame (NaN stays NaN)."""
        return self.p[6] if self.frame in RELATIVE_FRAMES else self.p[6] - home_alt_m


Then = Callable[[], object] | None
Outcome = int | tuple[int, Then]


def arm_disarm(v: Host, c: Command) -> Outcome:
    force = c.i(1) == FORCE_MAGIC
    if not math.isfinite(c.p[0]):
        return M.MAV_RESULT_DENIED
    if c.p[0] >= 0.5:
        if v.fix is None and not force:
            v.statustext("Arming denied: no GPS fix", M.MAV_SEVERITY_CRITICAL)
            return M.MAV_RESULT_TEMPORARILY_REJECTED
        if v.fences.breached and not force:  # GeofenceChecks: outside the polygon fence
            v.statustext("Geofence: approaching or outside geofence", M.MAV_SEVERITY_CRITICAL)
            v.statustext("Arming denied: Resolve system health failures first\t", M.MAV_SEVERITY_CRITICAL)
            return M.MAV_RESULT_TEMPORARILY_REJECTED
        return M.MAV_RESULT_ACCEPTED if v.arm() else M.MAV_RESULT_DENIED
    if v.model.disarm(force=force):
        return M.MAV_RESULT_ACCEPTED
    v.statustext("Disarming denied: in air", M.MAV_SEVERITY_WARNING)
    return M.MAV_RESULT_DENIED


def do_set_mode(v: Host, c: Command) -> Outcome:
    name = px4_mode_name(c.i(1), c.i(2)) if c.i(0) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED else None
    s = v.model.state
    if name is None:
        return M.MAV_RESULT_UNSUPPORTED
    if name in ATTITUDE_MODES:
        v.statustext(f"{name} not flown here: use POSCTL, AUTO or OFFBOARD", M.MAV_SEVERITY_WARNING)
        return M.MAV_RESULT_DENIED
    if name == "POSCTL" and not v.manual_fresh():
        v.statustext("POSCTL denied: no manual control input", M.MAV_SEVERITY_WARNING)
        return M.MAV_RESULT_TEMPORARILY_REJECTED
    if name == "OFFBOARD" and not v.offboard_fresh():
        v.statustext("Offboard denied: stream setpoints first", M.MAV_SEVERITY_WARNING)
        return M.MAV_RESULT_TEMPORARILY_REJECTED
    if name == "AUTO.MISSION" and not v.mission.items:
        return M.MAV_RESULT_DENIED
    if name == "AUTO.RTL" and (not s.armed or s.landed):
        return M.MAV_RESULT_TEMPORARILY_REJECTED
    if name == "AUTO.TAKEOFF":  # as PX4: the mode itself climbs to MIS_TAKEOFF_ALT
        return v.takeoff(math.nan)
    v.set_mode(name)
    return M.MAV_RESULT_ACCEPTED


def nav_takeoff(v: Host, c: Command) -> Outcome:
    return v.takeoff(c.p[6] if not c.is_int or c.frame not in RELATIVE_FRAMES else c.p[6] + v.home.alt_m)


def nav_land(v: Host, c: Command) -> Outcome:
    s = v.model.state
    if not s.armed:
        # on the ground: landed is what was asked, so it is done (PX4 accepts LAND on the ground
        # too). A LAND resent over a lossy link, its first ACK lost, arrives after the vehicle has
        # landed and disarmed (at 10x, 3.5 m down takes 0.6 wall s): refusing it told the sender
        # the landing had failed, and a 64-move search through 20 % loss ended as a failure.
        return M.MAV_RESULT_ACCEPTED if s.landed else M.MAV_RESULT_TEMPORARILY_REJECTED
    v.set_mode("AUTO.LAND")
    return M.MAV_RESULT_ACCEPTED


def nav_return_to_launch(v: Host, c: Command) -> Outcome:
    s = v.model.state
    if not s.armed or s.landed:
        return M.MAV_RESULT_TEMPORARILY_REJECTED
    v.set_mode("AUTO.RTL")
    return M.MAV_RESULT_ACCEPTED


def mission_start(v: Host, c: Command) -> Outcome:
    if not v.mission.items:
        return M.MAV_RESULT_DENIED
    v.mission.current = min(max(c.i(0), 0), len(v.mission.items) - 1)
    v.set_mode("AUTO.MISSION")
    return M.MAV_RESULT_ACCEPTED


def do_reposition(v: Host, c: Command) -> Outcome:
    s = v.model.state
    if not s.armed or s.landed:
        return M.MAV_RESULT_TEMPORARILY_REJECTED
    lat, lon = c.lat_lon()
    ned = v.estimate()
    if math.isfinite(lat) and math.isfinite(lon):
        ned[:2] = v.home.geodetic_to_ned(lat, lon, v.home.alt_m)[:2]
    rel = c.rel_alt(v.home.alt_m)
    if math.isfinite(rel):
        ned[2] = -rel
    speed = c.p[0] if math.isfinite(c.p[0]) and c.p[0] > 0 else None
    if not v.goto(ned, speed):
        return M.MAV_RESULT_DENIED
    v.mode = "AUTO.LOITER"
    return M.MAV_RESULT_ACCEPTED


def do_change_speed(v: Host, c: Command) -> Outcome:
    ok, why = v.params.set("MPC_XY_CRUISE", float(c.p[1]))
    if not ok:
        v.statustext(f"Speed refused: {why}", M.MAV_SEVERITY_WARNING)
        return M.MAV_RESULT_DENIED
    v.retarget(speed=float(c.p[1]))
    return M.MAV_RESULT_ACCEPTED


def set_message_interval(v: Host, c: Command) -> Outcome:
    msg_id, interval = c.i(0), c.p[1]
    if not (math.isfinite(c.p[0]) and math.isfinite(interval)):
        return M.MAV_RESULT_DENIED  # NaN is no message id, and no interval
    if msg_id not in DEFAULT_RATES and msg_id != M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
        return M.MAV_RESULT_UNSUPPORTED
    if msg_id == M.MAVLINK_MSG_ID_HEARTBEAT and (interval < 0 or interval > 1e6 * HEARTBEAT_MAX_PERIOD_S):
        # every peer's link-loss detection hangs on it: no peer may switch it off
        v.statustext("HEARTBEAT cannot be switched off", M.MAV_SEVERITY_WARNING)
        return M.MAV_RESULT_DENIED
    hz = DEFAULT_RATES.get(msg_id, 0.0) if interval == 0 else (0.0 if interval < 0 else 1e6 / interval)
    v.set_rate(msg_id, min(hz, MAX_STREAM_HZ))
    return M.MAV_RESULT_ACCEPTED


def inject_failure(v: Host, c: Command) -> Outcome:
    """MAV_CMD_INJECT_FAILURE: param1 FAILURE_UNIT, param2 FAILURE_TYPE (failsafe.py). The ACK
    goes out before the failure takes effect (a failed link would swallow it)."""
    if not (math.isfinite(c.p[0]) and math.isfinite(c.p[1])):
        return M.MAV_RESULT_DENIED
    return v.inject_failure(c.i(0), c.i(1))


def request_message(v: Host, c: Command) -> Outcome:
    msg_id = c.i(0)
    if not math.isfinite(c.p[0]):
        return M.MAV_RESULT_DENIED
    if msg_id == M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE:
        # as real PX4: the flight controller serves no camera frames (the camera component,
        # component 100, does: camera_component.py)
        return M.MAV_RESULT_DENIED
    if msg_id not in REQUESTABLE:
        return M.MAV_RESULT_UNSUPPORTED
    if msg_id == M.MAVLINK_MSG_ID_GPS_RAW_INT and v.fix is None:
        return M.MAV_RESULT_TEMPORARILY_REJECTED
    return M.MAV_RESULT_ACCEPTED, lambda: v.send_message(msg_id)


def request_autopilot_capabilities(v: Host, c: Command) -> Outcome:
    return M.MAV_RESULT_ACCEPTED, lambda: v.send_message(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)


def get_home_position(v: Host, c: Command) -> Outcome:
    return M.MAV_RESULT_ACCEPTED, lambda: v.send_message(M.MAVLINK_MSG_ID_HOME_POSITION)


HANDLERS: dict[int, Callable[[Host, Command], Outcome]] = {
    M.MAV_CMD_COMPONENT_ARM_DISARM: arm_disarm,
    M.MAV_CMD_DO_SET_MODE: do_set_mode,
    M.MAV_CMD_NAV_TAKEOFF: nav_takeoff,
    M.MAV_CMD_NAV_LAND: nav_land,
    M.MAV_CMD_NAV_RETURN_TO_LAUNCH: nav_return_to_launch,
    M.MAV_CMD_MISSION_START: mission_start,
    M.MAV_CMD_DO_REPOSITION: do_reposition,
    M.MAV_CMD_DO_CHANGE_SPEED: do_change_speed,
    M.MAV_CMD_SET_MESSAGE_INTERVAL: set_message_interval,
    M.MAV_CMD_REQUEST_MESSAGE: request_message,
    M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: request_autopilot_capabilities,
    M.MAV_CMD_GET_HOME_POSITION: get_home_position,
    M.MAV_CMD_INJECT_FAILURE: inject_failure,
}


def execute(v: Host, c: Command) -> tuple[int, Then]:
    """Run one command: (MAV_RESULT for the ACK, what to send after it)."""
    handler = HANDLERS.get(c.id)
    if handler is None:
        return M.MAV_RESULT_UNSUPPORTED, None
    out = handler(v, c)
    return out if isinstance(out, tuple) else (out, None)

