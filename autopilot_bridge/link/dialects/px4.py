"""PX4 (HEARTBEAT.autopilot 12): modes as px4_custom_mode.h packs them, the take-off in
AUTO.TAKEOFF then OFFBOARD, and the offboard-loss failsafe a dead companion relies on.

Facts from PX4 main of 2026-08 (commander_params.yaml, rtl_params.yaml, mavlink_main.cpp):
its onboard link already streams what the companion reads (LOCAL_POSITION_NED 30 Hz,
GPS_RAW_INT per fix, HOME_POSITION, EXTENDED_SYS_STATE), so nothing is asked for; integer
parameters travel bytewise in PARAM_VALUE's float.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import px4_modes
from .base import Dialect, FailsafeRule, FenceParam

#: COM_OBL_RC_ACT values after which a vehicle without its companion comes down: 3 Return,
#: 4 Land; 0-2 (Position, Altitude, Stabilized) fall back to Return without RC (measured on
#: the SITL: no RC, COM_OBL_RC_ACT 0 -> AUTO.RTL) and with RC leave the vehicle to its pilot.
#: 5 Hold hovers until the battery failsafe; 6 Terminate and 7 Disarm drop it from the sky.
OBL_SAFE = (0, 1, 2, 3, 4)
PREARM = mavlink.MAV_SYS_STATUS_PREARM_CHECK
#: GF_ACTION (geofence_params.yaml): what a fence breach does; 0 and 1 do nothing to the vehicle
GF_ACTIONS = {0: "None", 1: "Warning", 2: "Hold", 3: "Return", 4: "Terminate", 5: "Land"}
OBL_NAMES = {0: "Position", 1: "Altitude", 2: "Stabilized", 3: "Return", 4: "Land", 5: "Hold",
             6: "Terminate", 7: "Disarm"}


class PX4(Dialect):
    name = "px4"
    autopilot = mavlink.MAV_AUTOPILOT_PX4
    guided_mode = "OFFBOARD"
    land_mode = "AUTO.LAND"
    rtl_mode = "AUTO.RTL"
    hold_mode = "AUTO.LOITER"
    guided_before_arming = False
    takeoff_relative = False
    streams = ()
    param_bytewise = True

    def decode_mode(self, custom_mode: int) -> str:
        return px4_modes.decode(custom_mode)

    def set_mode_params(self, name: str) -> tuple[float, float, float]:
        main, sub = px4_modes.encode(name)
        return float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(main), float(sub)

    def not_ready(self, telemetry) -> str | None:
        """GPS and home, and PX4's own pre-arm checks passed: SYS_STATUS sets the PREARM_CHECK
        bit in its health mask (not in its present mask) once they pass; arming before that is
        TEMPORARILY_REJECTED (measured: the SIH's "no heading reference" for ~1 s after its fix)."""
        missing = super().not_ready(telemetry)
        if missing is None and not telemetry.sensors_health & PREARM:
            return "PX4's pre-arm checks (SYS_STATUS health)"
        return missing

    def failsafe_rules(self, companion_sysid: int) -> tuple[FailsafeRule, ...]:
        return (
            FailsafeRule("COM_OF_LOSS_T", lambda v: 0 < v <= 10, 1.0,
                         "the offboard-loss timeout: without setpoints for this long the vehicle leaves "
                         "OFFBOARD (0 or long: a dead companion's last setpoint is held)"),
            FailsafeRule("COM_OBL_RC_ACT", lambda v: int(v) in OBL_SAFE, 3.0,
                         "the offboard-loss action: " + ", ".join(f"{k} {v}" for k, v in OBL_NAMES.items())
                         + "; Hold hovers until the battery runs low, Terminate and Disarm drop the vehicle"),
            FailsafeRule("RTL_LAND_DELAY", lambda v: v >= 0, 0.0,
                         "Return's delay before landing (-1: it loiters over home for ever)", default=0.0),
        )

    def fence_params(self) -> tuple[FenceParam, ...]:
        """PX4 enforces every uploaded polygon at once; GF_ACTION says what a breach does (0 None
        and 1 Warning leave the vehicle flying out: set to 2 Hold, PX4's default)."""
        return (FenceParam("GF_ACTION", lambda v: int(v) in (2, 3, 4, 5), lambda v: 2.0,
                           "the fence breach action: " + ", ".join(f"{k} {n}" for k, n in GF_ACTIONS.items())),)
