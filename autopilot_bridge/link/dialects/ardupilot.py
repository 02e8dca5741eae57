"""ArduPilot's ArduCopter (HEARTBEAT.autopilot 3): its mode numbers, the take-off in GUIDED,
telemetry only when asked for, readiness by the EKF, and the GCS failsafe.

Facts from ArduPilot master of 2024-05 (ArduCopter/mode.h, events.cpp, Parameters.cpp,
GCS_Common.cpp, AP_GPS.cpp): GUIDED holds its last position target for ever when the
companion stops sending; only the GCS failsafe (FS_GCS_ENABLE, FS_GCS_TIMEOUT) brings it down,
and it watches the heartbeats of system SYSID_MYGCS alone (255 by default: a ground station,
not this companion). Arming wants EKF_STATUS_REPORT to show an absolute horizontal position.
GPS_RAW_INT.time_usec is the fix's boot time (last_fix_time_ms * 1000), as PX4's.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .base import COMMON_STREAMS, Dialect, FailsafeRule, FenceParam, Stream

#: ArduCopter's custom modes (ArduCopter/mode.h Mode::Number)
MODES = {"STABILIZE": 0, "ACRO": 1, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6,
         "CIRCLE": 7, "LAND": 9, "DRIFT": 11, "SPORT": 13, "FLIP": 14, "AUTOTUNE": 15, "POSHOLD": 16,
         "BRAKE": 17, "THROW": 18, "AVOID_ADSB": 19, "GUIDED_NOGPS": 20, "SMART_RTL": 21, "FLOWHOLD": 22,
         "FOLLOW": 23, "ZIGZAG": 24, "SYSTEMID": 25, "AUTOROTATE": 26, "AUTO_RTL": 27, "TURTLE": 28}
_NAMES = {v: k for k, v in MODES.items()}
#: FS_GCS_ENABLE values that bring the vehicle down: 1 RTL, 2 (RTL; its mission variant was
#: removed in 4.0), 3 SmartRTL or RTL, 4 SmartRTL or Land, 5 Land, 6 DO_LAND_START or RTL,
#: 7 Brake or Land; 0 disables the failsafe
GCS_FS_ACTIONS = {1: "RTL", 2: "RTL", 3: "SmartRTL or RTL", 4: "SmartRTL or Land", 5: "Land",
                  6: "Auto DO_LAND_START or RTL", 7: "Brake or Land"}
FENCE_TYPE_POLYGON = 4  # AC_FENCE_TYPE_POLYGON: inclusion/exclusion polygons and circles
#: FENCE_ACTION (AC_Fence.cpp, Copter): 0 reports only
FENCE_ACTIONS = {0: "Report Only", 1: "RTL or Land", 2: "Always Land", 3: "SmartRTL or RTL or Land",
                 4: "Brake or Land", 5: "SmartRTL or Land"}
#: EKF_STATUS_REPORT flags
EKF_POS_HORIZ_ABS = 16
EKF_CONST_POS_MODE = 128


class ArduPilot(Dialect):
    name = "ardupilot"
    autopilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    guided_mode = "GUIDED"
    land_mode = "LAND"
    rtl_mode = "RTL"
    hold_mode = "BRAKE"  # LOITER follows the throttle stick; BRAKE holds without one
    guided_before_arming = True
    takeoff_relative = True
    streams = COMMON_STREAMS + (
        Stream(mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT, 2.0),
        Stream(mavlink.MAVLINK_MSG_ID_SYSTEM_TIME, 1.0),
        Stream(mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, 0.5),
    )
    param_bytewise = False
    heartbeat_feeds_failsafe = True

    def decode_mode(self, custom_mode: int) -> str:
        return _NAMES.get(custom_mode, f"MODE{custom_mode}")

    def set_mode_params(self, name: str) -> tuple[float, float, float]:
        key = name.upper()
        if key not in MODES:
            raise ValueError(f"unknown ArduCopter mode {name!r}; known: {sorted(MODES)}")
        return float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(MODES[key]), 0.0

    def not_ready(self, telemetry) -> str | None:
        missing = super().not_ready(telemetry)
        if missing is not None:
            return missing
        flags = telemetry.ekf_flags
        if flags is None:
            return "an EKF_STATUS_REPORT"
        if not flags & EKF_POS_HORIZ_ABS or flags & EKF_CONST_POS_MODE:
            return f"an absolute horizontal position from the EKF (EKF_STATUS_REPORT flags {flags:#x})"
        return None

    def failsafe_rules(self, companion_sysid: int) -> tuple[FailsafeRule, ...]:
        return (
            FailsafeRule("FS_GCS_ENABLE", lambda v: int(v) in GCS_FS_ACTIONS, 1.0,
                         "the GCS failsafe: 0 disables it, and GUIDED then holds a dead companion's last "
                         "setpoint for ever; " + ", ".join(f"{k} {v}" for k, v in GCS_FS_ACTIONS.items())),
            FailsafeRule("FS_GCS_TIMEOUT", lambda v: 0 < v <= 30, 5.0,
                         "seconds without the watched heartbeat before the GCS failsafe acts", default=5.0),
            FailsafeRule("SYSID_MYGCS", lambda v: int(v) == companion_sysid, float(companion_sysid),
                         f"the system whose heartbeats feed the GCS failsafe: this companion is system "
                         f"{companion_sysid}; watching another (a ground station's 255) a dead companion goes "
                         "unnoticed while that one lives"),
            FailsafeRule("RTL_ALT_FINAL", lambda v: v == 0, 0.0,
                         "RTL's final altitude (cm): above 0 RTL hovers there instead of landing", default=0.0),
        )

    def fence_params(self) -> tuple[FenceParam, ...]:
        """AC_Fence: polygons are enforced only with FENCE_TYPE bit 4 and FENCE_ENABLE 1 (both
        checked when a breach is); FENCE_ACTION 0 only reports (set to 1, RTL or Land, its
        default). FENCE_ENABLE last, once the rest is right."""
        return (
            FenceParam("FENCE_TYPE", lambda v: bool(int(v) & FENCE_TYPE_POLYGON),
                       lambda v: float(int(v) | FENCE_TYPE_POLYGON),
                       "fence types bitmask: 4 selects the polygons (1 max altitude, 2 circle, 8 min altitude)"),
            FenceParam("FENCE_ACTION", lambda v: int(v) != 0, lambda v: 1.0,
                       "the fence breach action: " + ", ".join(f"{k} {n}" for k, n in FENCE_ACTIONS.items())),
            FenceParam("FENCE_ENABLE", lambda v: int(v) == 1, lambda v: 1.0, "the fence on (1) or off (0)"),
        )
