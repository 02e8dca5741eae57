"""One dialect object per autopilot family: how the simulated vehicle speaks and behaves as
that family's autopilot does (HEARTBEAT, mode names and numbers, which commands are taken in
which mode, take-off, setpoints, failsafe parameters, telemetry streams). The vehicle holds one
(`MavlinkVehicle.dialect`) and hands it every message and tick where the families differ, so
no `if px4:` is scattered through the vehicle.

- px4.py: PX4 SITL, the vehicle's behaviour before dialects existed (the default, unchanged).
- ardupilot.py, ardupilot_commands.py: ArduCopter (master of 2024-05), looked up in its source.

A dialect instance belongs to one vehicle: it may keep state of its own (the ArduCopter EKF's
start-up delay, its GCS failsafe).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import common as mavlink

from ..commands import Command
from ..host import Host
from ..params import ParamStore

M = mavlink
Builder = Callable[[Any, Any], Any]  # (encoder, Snapshot) -> message or None


class Dialect:
    """The interface; px4.PX4 and ardupilot.ArduPilot fill it in."""

    name: str = ""
    autopilot: int = M.MAV_AUTOPILOT_GENERIC
    initial_mode: str = ""
    #: modes in which the position target is re-flown in the estimate frame on every GPS fix
    tracking_modes: frozenset[str] = frozenset()
    #: the fleet may build this dialect's telemetry with numpy and step it with quiet ticks
    #: (fleet_telemetry.py, quiet.py: PX4's messages and modes only)
    fleet_vectorised: bool = False
    #: telemetry builders by message id (telemetry.py's Snapshot in, a message out)
    builders: dict[int, Builder] = {}

    def default_rates(self) -> dict[int, float]:
        """Streams sent unasked, Hz by message id."""
        raise NotImplementedError

    def param_store(self, signing: bool, armed: Callable[[], bool]) -> ParamStore:
        raise NotImplementedError

    def execute(self, v: Host, c: Command) -> tuple[int, Callable[[], object] | None]:
        """One COMMAND_LONG / COMMAND_INT: (MAV_RESULT for the ACK, what to do after it)."""
        raise NotImplementedError

    def on_set_mode(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """The deprecated SET_MODE message (no ACK)."""

    def on_setpoint(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT."""

    def heard_heartbeat(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """A peer's HEARTBEAT (what the link-loss failsafe watches)."""

    def on_message(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """Any other message the vehicle does not answer itself (REQUEST_DATA_STREAM, ...)."""

    def set_mode(self, v: Host, mode: str) -> None:
        """Enter a mode (no checks: the caller has made them) and do what entering it does."""
        raise NotImplementedError

    def step(self, v: Host) -> None:
        """Every tick, after the battery: failsafes, then the flying of the mode."""
        raise NotImplementedError

    def fence_protocol(self, v: Any, clock: Callable[[], float]) -> Any:
        """The family's MAV_MISSION_TYPE_FENCE protocol (fence_protocol.py) for vehicle v;
        None: fence uploads are answered as unsupported."""
        return None


def make_dialect(name: str, **options: Any) -> Dialect:
    """The dialect called `name` (px4 | ardupilot), built with its options."""
    if name == "px4":
        from .px4 import PX4

        return PX4(**options)
    if name == "ardupilot":
        from .ardupilot import ArduPilot

        return ArduPilot(**options)
    raise ValueError(f"dialect must be one of {', '.join(DIALECTS)} (got {name!r})")


DIALECTS = ("px4", "ardupilot")
