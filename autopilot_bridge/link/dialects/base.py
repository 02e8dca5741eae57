"""What the companion must know about an autopilot family, in one object.

The search loop, the pilot and the bring-down speak in roles ("the mode setpoints are flown
in", "land", "return", "hold"); a dialect maps each role to its family's modes and commands,
says which telemetry to ask for and when the vehicle is ready to arm, and which parameters
decide whether a dead companion leaves the vehicle flying. No `if px4:` elsewhere.
"""

from __future__ import annotations

import struct
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink


@dataclass(frozen=True)
class FailsafeRule:
    """One parameter the companion-loss failsafe depends on: `ok(value)` says whether a
    killed companion would still see the vehicle brought down; `safe` is the value
    `--set-failsafe` writes and the refusal suggests. `default` stands for a vehicle that
    does not have the parameter (an older firmware, or our emulation)."""

    name: str
    ok: Callable[[float], bool]
    safe: float
    why: str
    default: float | None = None


@dataclass(frozen=True)
class FenceParam:
    """A parameter the uploaded fence needs to be enforced: `ok(value)` says whether it is;
    `fix(value)` is what the companion writes when not (autopilot_bridge.service.fence.enable)."""

    name: str
    ok: Callable[[float], bool]
    fix: Callable[[float], float]
    why: str


@dataclass(frozen=True)
class Stream:
    """A message the companion needs, at the rate it needs it (SET_MESSAGE_INTERVAL)."""

    msg_id: int
    hz: float


#: what every dialect asks for: GPS fixes at the receiver's 5 Hz, the autopilot's estimate at
#: 10 Hz (the settle check reads it), the global position and home for the frames
COMMON_STREAMS = (
    Stream(mavlink.MAVLINK_MSG_ID_GPS_RAW_INT, 5.0),
    Stream(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 10.0),
    Stream(mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 10.0),
    Stream(mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 2.0),
    Stream(mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0.5),
    Stream(mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, 1.0),
)


class Dialect(ABC):
    """One autopilot family. Subclasses fill in the class attributes and the mode codec."""

    name: str
    autopilot: int  # HEARTBEAT.autopilot (MAV_AUTOPILOT_*)
    #: the mode in which the companion's position setpoints are flown
    guided_mode: str
    land_mode: str
    rtl_mode: str
    hold_mode: str
    #: the vehicle switches to guided_mode before arming (ArduCopter takes off in GUIDED),
    #: rather than after the take-off (PX4 takes off in AUTO.TAKEOFF, then OFFBOARD)
    guided_before_arming: bool
    #: the take-off's altitude is above home (ArduPilot) rather than AMSL (PX4)
    takeoff_relative: bool
    #: SET_MESSAGE_INTERVAL requests at connection
    streams: tuple[Stream, ...] = COMMON_STREAMS
    #: PARAM_VALUE carries integer parameters' bytes in the float (PX4), not their value cast
    param_bytewise: bool = False
    #: the companion-loss failsafe watches the companion's HEARTBEAT (ArduPilot's GCS failsafe)
    #: rather than its setpoints (PX4's offboard loss): a hung decision loop must then stop both
    heartbeat_feeds_failsafe: bool = False

    @abstractmethod
    def decode_mode(self, custom_mode: int) -> str:
        """HEARTBEAT.custom_mode -> the family's mode name."""

    @abstractmethod
    def set_mode_params(self, name: str) -> tuple[float, float, float]:
        """The family's mode name -> MAV_CMD_DO_SET_MODE params 1-3; ValueError names the mode."""

    def descending(self, mode: str) -> bool:
        """Whether the vehicle in this mode is already on its way down (land or return)."""
        return mode in (self.land_mode, self.rtl_mode)

    def takeoff_altitude(self, home_alt_amsl: float, above_home_m: float) -> float:
        """MAV_CMD_NAV_TAKEOFF's param 7 for a climb to above_home_m over home."""
        return above_home_m if self.takeoff_relative else home_alt_amsl + above_home_m

    def not_ready(self, telemetry) -> str | None:
        """What the vehicle still lacks before the companion may arm it (None: ready)."""
        if telemetry.gps.get("fix_type", 0) < 3:
            return "a 3D GPS fix"
        if not telemetry.home:
            return "a home position"
        return None

    @abstractmethod
    def failsafe_rules(self, companion_sysid: int) -> tuple[FailsafeRule, ...]:
        """The parameters that decide what the vehicle does when this companion dies."""

    def fence_params(self) -> tuple[FenceParam, ...]:
        """The parameters that make an uploaded polygon fence enforced, in the order to set them."""
        return ()

    def param_value(self, value: float, param_type: int) -> float:
        """PARAM_VALUE.param_value -> the parameter's value."""
        if self.param_bytewise and param_type in _INT_TYPES:
            raw = struct.pack("<f", value)
            fmt = _INT_TYPES[param_type]
            return float(struct.unpack(fmt, raw[:struct.calcsize(fmt)])[0])
        return float(value)

    def param_encode(self, value: float, param_type: int) -> float:
        """A value -> PARAM_SET.param_value for a parameter of this type."""
        if self.param_bytewise and param_type in _INT_TYPES:
            fmt = _INT_TYPES[param_type]
            raw = struct.pack(fmt, int(round(value))).ljust(4, b"\0")
            return struct.unpack("<f", raw)[0]
        return float(value)

    def __repr__(self) -> str:
        return f"<{self.name} dialect>"


_INT_TYPES = {
    mavlink.MAV_PARAM_TYPE_UINT8: "<B", mavlink.MAV_PARAM_TYPE_INT8: "<b",
    mavlink.MAV_PARAM_TYPE_UINT16: "<H", mavlink.MAV_PARAM_TYPE_INT16: "<h",
    mavlink.MAV_PARAM_TYPE_UINT32: "<I", mavlink.MAV_PARAM_TYPE_INT32: "<i",
}
