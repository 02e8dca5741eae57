"""ArduCopter's telemetry, as its GCS_MAVLink sends it (ArduCopter/GCS_Mavlink.cpp,
libraries/GCS_MAVLink/GCS_Common.cpp, libraries/AP_GPS/AP_GPS.cpp at fbb785859a, 2024-05).

- HEARTBEAT: type QUADROTOR, autopilot ARDUPILOTMEGA (3), custom_mode = the mode number,
  base_mode = STABILIZE_ENABLED | MANUAL_INPUT_ENABLED | CUSTOM_MODE_ENABLED, GUIDED_ENABLED in
  the navigating modes (AUTO, RTL, LOITER, GUIDED, BRAKE, ...), SAFETY_ARMED when armed
  (GCS_MAVLINK_Copter::base_mode); system_status CRITICAL while a failsafe is on, STANDBY on
  the ground, ACTIVE in the air (vehicle_system_status).
- GPS_RAW_INT.time_usec: the *boot* time of the last fix, in whole ms, times 1000
  (AP_GPS::send_mavlink_gps_raw: last_fix_time_ms(0) * 1000) - not the GPS's UTC time.
- SYSTEM_TIME: time_unix_usec from the RTC, which the GPS sets (0 until it has), and
  time_boot_ms (GCS_MAVLINK::send_system_time): what maps boot time to UTC.
- EKF_STATUS_REPORT (ardupilotmega.xml): flags 831 (attitude, velocities, relative and absolute
  horizontal position, absolute vertical, predicted positions) once the EKF has GPS, and 165
  (attitude, vertical velocity, absolute vertical, CONST_POS_MODE) before.
- GPS_GLOBAL_ORIGIN: the EKF origin, which MAV_FRAME_LOCAL_NED setpoints and
  LOCAL_POSITION_NED are relative to (home here: the vehicle does not move before its EKF
  is ready).
- AUTOPILOT_VERSION: 4.6.0-dev (the tree's version.h), git hash fbb78585.
The rest (SYS_STATUS, GLOBAL_POSITION_INT, LOCAL_POSITION_NED, ATTITUDE, VFR_HUD,
BATTERY_STATUS, EXTENDED_SYS_STATE, HOME_POSITION) are telemetry.py's, on the same state."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as apm
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import to_e7

from .. import telemetry
from ..telemetry import Snapshot
from .ardupilot_modes import CopterState

M = mavlink
#: EKF_STATUS_REPORT flags (ardupilotmega EKF_STATUS_FLAGS)
EKF_READY_FLAGS = (apm.EKF_ATTITUDE | apm.EKF_VELOCITY_HORIZ | apm.EKF_VELOCITY_VERT | apm.EKF_POS_HORIZ_REL
                   | apm.EKF_POS_HORIZ_ABS | apm.EKF_POS_VERT_ABS | apm.EKF_PRED_POS_HORIZ_REL
                   | apm.EKF_PRED_POS_HORIZ_ABS)  # 831
EKF_WAITING_FLAGS = apm.EKF_ATTITUDE | apm.EKF_VELOCITY_VERT | apm.EKF_POS_VERT_ABS | apm.EKF_CONST_POS_MODE  # 165
#: ArduCopter 4.6.0-dev (major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE_DEV)
FLIGHT_SW_VERSION = (4 << 24) | (6 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_DEV
GIT_HASH = b"fbb78585"
CAPABILITIES = telemetry.CAPABILITIES | M.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
#: modes whose HEARTBEAT carries GUIDED_ENABLED (GCS_MAVLINK_Copter::base_mode)
GUIDED_FLAG_MODES = frozenset({"AUTO", "RTL", "LOITER", "GUIDED", "BRAKE"})


class Builders:
    """The message builders of one ArduPilot vehicle (they read its dialect's state)."""

    def __init__(self, d: CopterState) -> None:
        self.d = d

    def table(self) -> dict[int, Any]:
        b = dict(telemetry.BUILDERS)
        b.update({
            M.MAVLINK_MSG_ID_HEARTBEAT: self.heartbeat,
            M.MAVLINK_MSG_ID_GPS_RAW_INT: self.gps_raw_int,
            M.MAVLINK_MSG_ID_SYSTEM_TIME: self.system_time,
            apm.MAVLINK_MSG_ID_EKF_STATUS_REPORT: self.ekf_status_report,
            M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: self.gps_global_origin,
            M.MAVLINK_MSG_ID_HOME_POSITION: self.home_position,
            M.MAVLINK_MSG_ID_AUTOPILOT_VERSION: self.autopilot_version,
        })
        return b

    def heartbeat(self, enc: Any, x: Snapshot) -> Any:
        s = x.state
        base = M.MAV_MODE_FLAG_STABILIZE_ENABLED | M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if x.mode in GUIDED_FLAG_MODES:
            base |= M.MAV_MODE_FLAG_GUIDED_ENABLED
        if s.armed:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
        status = (M.MAV_STATE_CRITICAL if self.d.gcs_failsafe else
                  M.MAV_STATE_STANDBY if s.landed else M.MAV_STATE_ACTIVE)
        return enc.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                                    self.d.custom_mode(x.mode), status)

    def gps_raw_int(self, enc: Any, x: Snapshot) -> Any:
        f = x.fix
        if f is None:
            return None
        fix_ms = math.floor(f.time_s * 1000.0 + 1e-6)  # the boot time the fix arrived at, in ms
        vn, ve = float(f.vel_ned[0]), float(f.vel_ned[1])
        cog = int(math.degrees(math.atan2(ve, vn)) % 360.0 * 100)  # ground_course(0) * 100
        return enc.gps_raw_int_encode(fix_ms * 1000, f.fix_type, to_e7(f.lat_deg), to_e7(f.lon_deg),
                                      int(f.alt_m * 1000), int(f.eph_m * 100), int(f.epv_m * 100),
                                      int(math.hypot(vn, ve) * 100), cog, f.satellites_visible,
                                      0, int(f.eph_m * 1000), int(f.epv_m * 1000), 300, 0)

    def system_time(self, enc: Any, x: Snapshot) -> Any:
        return enc.system_time_encode(self.d.unix_usec(x.t), int(x.t * 1000))

    def ekf_status_report(self, enc: Any, x: Snapshot) -> Any:
        if self.d.position_ok(x.t, x.fix):
            flags, pos_var = EKF_READY_FLAGS, 0.02
        else:
            flags, pos_var = EKF_WAITING_FLAGS, 0.0
        return apm.MAVLink_ekf_status_report_message(flags, 0.02, pos_var, 0.02, 0.02, 0.0, 0.0)

    def gps_global_origin(self, enc: Any, x: Snapshot) -> Any:
        if not self.d.position_ok(x.t, x.fix):
            return None  # no origin yet: nothing to send
        h = x.home
        # time_usec: the boot time it is sent at (the real one's read 41659163 asked at ~41.6 s)
        return enc.gps_global_origin_encode(to_e7(h.lat_deg), to_e7(h.lon_deg), int(h.alt_m * 1000),
                                            int(x.t * 1e6))

    def home_position(self, enc: Any, x: Snapshot) -> Any:
        return telemetry.home_position(enc, x) if self.d.position_ok(x.t, x.fix) else None

    def autopilot_version(self, enc: Any, x: Snapshot) -> Any:
        return enc.autopilot_version_encode(CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, GIT_HASH, b"\0" * 8,
                                            b"\0" * 8, 0, 0, x.sysid, b"\0" * 18)
