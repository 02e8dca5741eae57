"""The vehicle's telemetry messages, built from one snapshot of its state.

What a PX4 vehicle streams and what MAVSDK and QGroundControl read before they call a vehicle
healthy: HEARTBEAT (honest armed / custom-mode flags), SYS_STATUS, GPS, position (the
autopilot's estimate, not the truth), attitude, landed state, battery and home.

MAVSDK's health (TelemetryImpl::process_sys_status) reads SYS_STATUS alone: gyro, accel and
mag "calibrated" = present and healthy bits of 3D_GYRO / 3D_ACCEL / 3D_MAG; global (and so
local) position ok = GPS present and healthy; armable = PREARM_CHECK healthy; home ok once a
HOME_POSITION arrives. So GPS health and the pre-arm bit follow the GPS fix here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import HomePosition, to_e7
from sim.vehicle.gps import GpsFix
from sim.vehicle.model import VehicleState

from .modes import px4_custom_mode

M = mavlink
SENSORS = (
    M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL | M.MAV_SYS_STATUS_SENSOR_3D_MAG
    | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE | M.MAV_SYS_STATUS_SENSOR_GPS
    | M.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL | M.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | M.MAV_SYS_STATUS_SENSOR_YAW_POSITION | M.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | M.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | M.MAV_SYS_STATUS_SENSOR_BATTERY | M.MAV_SYS_STATUS_AHRS | M.MAV_SYS_STATUS_GEOFENCE
)
#: what AUTOPILOT_VERSION claims: only what this vehicle does (no FTP, no fence/rally, no terrain)
CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)
#: PX4 v1.15.0 (major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE_OFFICIAL)
FLIGHT_SW_VERSION = (1 << 24) | (15 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_OFFICIAL
#: default telemetry rates (Hz) per message id; SET_MESSAGE_INTERVAL changes them
DEFAULT_RATES = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0, M.MAVLINK_MSG_ID_SYS_STATUS: 1.0, M.MAVLINK_MSG_ID_GPS_RAW_INT: 5.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 10.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 10.0, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 2.0,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0, M.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0, M.MAVLINK_MSG_ID_VFR_HUD: 4.0,
}


@dataclass(frozen=True)
class Snapshot:
    """What the telemetry may say: the true airframe state for attitude and flags, the
    autopilot's position estimate for positions, the last GPS fix."""

    t: float
    state: VehicleState
    estimate_ned: np.ndarray
    home: HomePosition
    fix: GpsFix | None
    mode: str
    sysid: int
    fence_breached: bool = False
    battery_ok: bool = True


def _heading_deg(s: VehicleState) -> float:
    return math.degrees(s.attitude_rpy[2]) % 360


def heartbeat(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    s = x.state
    base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED
    if s.armed:
        base |= M.MAV_MODE_FLAG_SAFETY_ARMED
    if x.mode.startswith("AUTO"):
        base |= M.MAV_MODE_FLAG_AUTO_ENABLED
    status = M.MAV_STATE_ACTIVE if s.armed else M.MAV_STATE_STANDBY
    return mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, base, px4_custom_mode(x.mode), status)


def sys_status(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    s = x.state
    present = SENSORS | M.MAV_SYS_STATUS_PREARM_CHECK
    health = SENSORS | M.MAV_SYS_STATUS_PREARM_CHECK if x.fix is not None else SENSORS & ~M.MAV_SYS_STATUS_SENSOR_GPS
    # the geofence is present, enabled and healthy unless breached, as PX4 reports it
    # (a ground station reads an absent health bit as a breach)
    if x.fence_breached:
        health &= ~M.MAV_SYS_STATUS_GEOFENCE
    if not x.battery_ok:
        health &= ~M.MAV_SYS_STATUS_SENSOR_BATTERY
    return mav.sys_status_encode(present, present, health, 250, int(s.battery_voltage * 1000), -1,
                                 int(s.battery_remaining * 100), 0, 0, 0, 0, 0, 0)


def gps_raw_int(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message | None:
    f = x.fix
    if f is None:
        return None
    return mav.gps_raw_int_encode(int(f.time_s * 1e6), f.fix_type, to_e7(f.lat_deg), to_e7(f.lon_deg),
                                  int(f.alt_m * 1000), int(f.eph_m * 100), int(f.epv_m * 100),
                                  int(np.hypot(*f.vel_ned[:2]) * 100), 65535, f.satellites_visible,
                                  0, int(f.eph_m * 1000), int(f.epv_m * 1000), 300, 0)


def global_position_int(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    est, v = x.estimate_ned, x.state.velocity_ned
    lat, lon, alt = x.home.ned_to_geodetic(est)
    return mav.global_position_int_encode(int(x.t * 1000), to_e7(lat), to_e7(lon), int(alt * 1000),
                                          int(-est[2] * 1000), int(v[0] * 100), int(v[1] * 100), int(v[2] * 100),
                                          int(_heading_deg(x.state) * 100))


def local_position_ned(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    return mav.local_position_ned_encode(int(x.t * 1000), *map(float, x.estimate_ned), *map(float, x.state.velocity_ned))


def attitude(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    r, p, y = map(float, x.state.attitude_rpy)
    return mav.attitude_encode(int(x.t * 1000), r, p, y, *map(float, x.state.body_rates))


def extended_sys_state(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    landed = M.MAV_LANDED_STATE_ON_GROUND if x.state.landed else M.MAV_LANDED_STATE_IN_AIR
    return mav.extended_sys_state_encode(M.MAV_VTOL_STATE_MC, landed)


def battery_status(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    s = x.state
    cells = [int(s.battery_voltage * 1000 / 4)] * 4 + [65535] * 6  # a 4S pack
    return mav.battery_status_encode(0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO, 2500, cells,
                                     -1, -1, -1, int(s.battery_remaining * 100))


def home_position(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    h = x.home
    return mav.home_position_encode(to_e7(h.lat_deg), to_e7(h.lon_deg), int(h.alt_m * 1000), 0, 0, 0,
                                    [1, 0, 0, 0], 0, 0, 0, int(x.t * 1e6))


def vfr_hud(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    s, v = x.state, x.state.velocity_ned
    speed = float(np.hypot(v[0], v[1]))
    return mav.vfr_hud_encode(speed, speed, int(_heading_deg(s)), 50 if s.armed else 0,
                              float(x.home.alt_m - x.estimate_ned[2]), float(-v[2]))


def autopilot_version(mav: mavlink.MAVLink, x: Snapshot) -> mavlink.MAVLink_message:
    return mav.autopilot_version_encode(CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, b"\0" * 8, b"\0" * 8, b"\0" * 8,
                                        0, 0, x.sysid, b"\0" * 18)


BUILDERS: dict[int, Callable[[mavlink.MAVLink, Snapshot], mavlink.MAVLink_message | None]] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: heartbeat,
    M.MAVLINK_MSG_ID_SYS_STATUS: sys_status,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: gps_raw_int,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: global_position_int,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: local_position_ned,
    M.MAVLINK_MSG_ID_ATTITUDE: attitude,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: extended_sys_state,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: battery_status,
    M.MAVLINK_MSG_ID_HOME_POSITION: home_position,
    M.MAVLINK_MSG_ID_VFR_HUD: vfr_hud,
    M.MAVLINK_MSG_ID_AUTOPILOT_VERSION: autopilot_version,
}
