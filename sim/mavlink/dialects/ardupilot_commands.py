"""COMMAND_LONG / COMMAND_INT as ArduCopter answers them (ArduCopter/GCS_Mavlink.cpp
GCS_MAVLINK_Copter::handle_command_int_packet, falling back to GCS_Common.cpp's): COMMAND_LONG
is run as COMMAND_INT (try_command_long_as_command_int; NAV_TAKEOFF's frame becomes
GLOBAL_RELATIVE_ALT); a command neither knows is MAV_RESULT_UNSUPPORTED; a known one that
cannot be done now is mostly FAILED (ArduPilot's habit, "often we should be returning DENIED
rather than FAILED here", GCS_Common.cpp)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from ..commands import Command
from ..host import Host
from .ardupilot_modes import ARMABLE, MODES, REQUIRES_GPS, USER_TAKEOFF, CopterState

M = mavlink
FORCE_ARM = 2989.0  # GCS_MAVLINK::magic_force_arm_value
FORCE_DISARM = 21196.0  # GCS_MAVLINK::magic_force_disarm_value
Then = Callable[[], object] | None
Outcome = int | tuple[int, Then]


def arm_disarm(d: CopterState, v: Host, c: Command) -> Outcome:
    """GCS_MAVLINK::handle_command_component_arm_disarm and AP_Arming_Copter::arm: every
    failed check is said as "Arm: ..." (running_arming_checks), the ACK is FAILED."""
    s = v.model.state
    if c.p[0] == 1.0:
        if s.armed:
            return M.MAV_RESULT_ACCEPTED
        if c.p[1] != FORCE_ARM:
            failed = []
            if int(v.params["FS_GCS_ENABLE"]) == 2:
                failed.append("FS_GCS_ENABLE=2 removed, see FS_OPTIONS")  # parameter_checks
            if d.gcs_failsafe:
                failed.append("GCS failsafe on")  # gcs_failsafe_check
            if d.polygon_fence_on(v) and v.fences.breached:  # fence_checks: AC_Fence::pre_arm_check
                failed.append("vehicle outside fence")
            if v.mode in REQUIRES_GPS and not d.position_ok(v.t, v.fix):  # mandatory_gps_checks
                failed.append("Need Position Estimate")
            elif not d.attitude_ok(v.t):  # the inertial sensors and the EKF's attitude settling
                failed.append("EKF attitude is bad")
            if not failed and v.mode not in ARMABLE:  # arm_checks run only after the pre-arm checks pass
                failed.append(f"{v.mode} mode not armable")
            if failed:
                for why in failed:
                    v.statustext(f"Arm: {why}", M.MAV_SEVERITY_CRITICAL)
                return M.MAV_RESULT_FAILED
        if not v.arm():
            return M.MAV_RESULT_FAILED
        v.statustext("Arming motors", M.MAV_SEVERITY_INFO)
        return M.MAV_RESULT_ACCEPTED
    if c.p[0] == 0.0:
        if not s.armed:
            return M.MAV_RESULT_ACCEPTED
        force = c.p[1] == FORCE_DISARM
        if not force and not s.landed:
            return M.MAV_RESULT_FAILED  # "do not allow disarm via mavlink if we think we are flying"
        return M.MAV_RESULT_ACCEPTED if v.model.disarm(force=force) else M.MAV_RESULT_FAILED
    return M.MAV_RESULT_UNSUPPORTED


def do_set_mode(d: CopterState, v: Host, c: Command) -> Outcome:
    """GCS_MAVLINK::_set_mode_common: param1 base mode (CUSTOM_MODE_ENABLED), param2 the mode."""
    if not (math.isfinite(c.p[0]) and math.isfinite(c.p[1])):
        return M.MAV_RESULT_DENIED
    if c.i(0) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return d.change_mode(v, c.i(1))
    return M.MAV_RESULT_DENIED  # only custom modes ("no easy mapping from MAVLink flight modes")


def nav_takeoff(d: CopterState, v: Host, c: Command) -> Outcome:
    """handle_MAV_CMD_NAV_TAKEOFF and Mode::do_user_takeoff: param7 metres above home, in
    GUIDED (or LOITER), armed and on the ground, above where it is."""
    if c.is_int and c.frame not in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
        return M.MAV_RESULT_DENIED
    s, alt = v.model.state, c.p[6]
    est = v.estimate()
    if not s.armed or not s.landed or v.mode not in USER_TAKEOFF or not math.isfinite(alt) or alt <= -est[2]:
        return M.MAV_RESULT_FAILED
    if not v.goto(np.array([est[0], est[1], -alt]), speed=v.params["MPC_XY_CRUISE"]):
        return M.MAV_RESULT_FAILED
    d.takeoff_z = -alt
    return M.MAV_RESULT_ACCEPTED


def to_mode(name: str) -> Callable[[CopterState, Host, Command], Outcome]:
    """NAV_LAND -> LAND, NAV_RETURN_TO_LAUNCH -> RTL, NAV_LOITER_UNLIM -> LOITER: set_mode or FAILED."""
    def run(d: CopterState, v: Host, c: Command) -> Outcome:
        return d.change_mode(v, MODES[name])

    return run


GLOBAL_ALT_FRAMES = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                               M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})


def do_reposition(d: CopterState, v: Host, c: Command) -> Outcome:
    """handle_command_int_do_reposition: COMMAND_INT only (COMMAND_LONG has no frame for it:
    UNSUPPORTED, as the real one answered); in GUIDED, or switching to it with
    MAV_DO_REPOSITION_FLAGS_CHANGE_MODE (param2 bit 0); lat/lon (x, y 1e7) and alt (z, by the
    frame) required; flown at once when airborne."""
    if not c.is_int:
        return M.MAV_RESULT_UNSUPPORTED
    change_mode = math.isfinite(c.p[1]) and int(c.p[1]) & M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
    if v.mode != "GUIDED" and not change_mode:
        return M.MAV_RESULT_DENIED
    lat, lon = c.lat_lon()
    if (not (abs(lat) <= 90 and abs(lon) <= 180) or (c.p[4] == 0 and c.p[5] == 0)
            or c.frame not in GLOBAL_ALT_FRAMES or not math.isfinite(c.p[6])):
        return M.MAV_RESULT_DENIED  # check_latlng, location_from_command_t, Location::sanitize
    ne = v.home.geodetic_to_ned(lat, lon, v.home.alt_m)
    ned = np.array([ne[0], ne[1], -c.rel_alt(v.home.alt_m)])
    if not v.fence().allows(ned) or not d.polygon_allows(v, ned):
        v.statustext("Geofence: reposition rejected", M.MAV_SEVERITY_WARNING)
        return M.MAV_RESULT_FAILED
    if v.mode != "GUIDED" and d.change_mode(v, MODES["GUIDED"]) != M.MAV_RESULT_ACCEPTED:
        return M.MAV_RESULT_FAILED
    s = v.model.state
    if s.armed and (not s.landed or d.takeoff_z is not None):
        d.takeoff_z = None
        v._target = ned
        v._command_model(ned, speed=v.params["MPC_XY_CRUISE"])
    return M.MAV_RESULT_ACCEPTED


def do_change_speed(d: CopterState, v: Host, c: Command) -> Outcome:
    """handle_MAV_CMD_DO_CHANGE_SPEED: param2 m/s > 0 (here: the target now flown, at that speed)."""
    if not (math.isfinite(c.p[1]) and c.p[1] > 0):
        return M.MAV_RESULT_FAILED
    v.retarget(speed=float(c.p[1]))
    return M.MAV_RESULT_ACCEPTED


def set_message_interval(d: CopterState, v: Host, c: Command) -> Outcome:
    """GCS_MAVLINK::set_message_interval: param2 interval in us; 0 the default (none for what
    is not streamed by default), -1 stop. A message it has no ap_message for is DENIED."""
    if not (math.isfinite(c.p[0]) and math.isfinite(c.p[1])):
        return M.MAV_RESULT_DENIED
    msg_id, interval = c.i(0), c.p[1]
    if msg_id not in v.builders and msg_id != M.MAVLINK_MSG_ID_MISSION_CURRENT:
        v.statustext(f"No ap_message for mavlink id ({msg_id})", M.MAV_SEVERITY_INFO)
        return M.MAV_RESULT_DENIED
    if interval == 0:
        hz = d.default_rates().get(msg_id, 0.0)
    elif interval < 0:
        hz = 0.0
    else:
        hz = 1e6 / min(max(interval, 1000.0), 60e6)
    v.set_rate(msg_id, min(hz, 50.0))  # at most 80 % of a 400 Hz loop in the real one; 50 here
    return M.MAV_RESULT_ACCEPTED


def request_message(d: CopterState, v: Host, c: Command) -> Outcome:
    """GCS_MAVLINK::handle_command_request_message: ACCEPTED and queued, FAILED for a message
    it has no ap_message for: DATA_TRANSMISSION_HANDSHAKE among them (no real autopilot
    serves camera frames: the camera component does, camera_component.py)."""
    if not math.isfinite(c.p[0]):
        return M.MAV_RESULT_FAILED
    msg_id = c.i(0)
    if msg_id not in v.builders and msg_id != M.MAVLINK_MSG_ID_MISSION_CURRENT:
        return M.MAV_RESULT_FAILED
    return M.MAV_RESULT_ACCEPTED, lambda: v.send_message(msg_id)


def send_after(msg_id: int) -> Callable[[CopterState, Host, Command], Outcome]:
    """MAV_CMD_GET_HOME_POSITION, MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: ACCEPTED, then the message."""

    def run(d: CopterState, v: Host, c: Command) -> Outcome:
        return M.MAV_RESULT_ACCEPTED, lambda: v.send_message(msg_id)

    return run


HANDLERS: dict[int, Callable[[CopterState, Host, Command], Outcome]] = {
    M.MAV_CMD_COMPONENT_ARM_DISARM: arm_disarm,
    M.MAV_CMD_DO_SET_MODE: do_set_mode,
    M.MAV_CMD_NAV_TAKEOFF: nav_takeoff,
    M.MAV_CMD_NAV_LAND: to_mode("LAND"),
    M.MAV_CMD_NAV_RETURN_TO_LAUNCH: to_mode("RTL"),
    M.MAV_CMD_NAV_LOITER_UNLIM: to_mode("LOITER"),
    M.MAV_CMD_DO_CHANGE_SPEED: do_change_speed,
    M.MAV_CMD_DO_REPOSITION: do_reposition,
    M.MAV_CMD_SET_MESSAGE_INTERVAL: set_message_interval,
    M.MAV_CMD_REQUEST_MESSAGE: request_message,
    M.MAV_CMD_GET_HOME_POSITION: send_after(M.MAVLINK_MSG_ID_HOME_POSITION),
    M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: send_after(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION),
}


def execute(d: CopterState, v: Host, c: Command) -> tuple[int, Then]:
    handler = HANDLERS.get(c.id)
    if handler is None:
        return M.MAV_RESULT_UNSUPPORTED, None
    out = handler(d, v, c)
    return out if isinstance(out, tuple) else (out, None)
