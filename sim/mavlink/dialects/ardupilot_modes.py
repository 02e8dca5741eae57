"""ArduCopter's flight modes: numbers (ArduCopter/mode.h Mode::Number) and what each mode
class says of itself (requires_GPS, allows_arming from a GCS, is_autopilot, has_user_takeoff);
and the dialect's state as its commands and telemetry read it (a Protocol, so those modules
need not import ardupilot.py, which imports them)."""

from __future__ import annotations

from typing import Any, Protocol

#: the modes flown here, by name and number (ArduCopter/mode.h)
MODES = {"STABILIZE": 0, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9, "BRAKE": 17}
NAMES = {n: name for name, n in MODES.items()}
#: ArduCopter's other modes, known by number but not flown here
OTHER_MODES = {1: "ACRO", 7: "CIRCLE", 11: "DRIFT", 13: "SPORT", 14: "FLIP", 15: "AUTOTUNE", 16: "POSHOLD",
               18: "THROW", 19: "AVOID_ADSB", 20: "GUIDED_NOGPS", 21: "SMART_RTL", 22: "FLOWHOLD", 23: "FOLLOW",
               24: "ZIGZAG", 25: "SYSTEMID", 26: "AUTOROTATE", 27: "AUTO_RTL", 28: "TURTLE"}
REQUIRES_GPS = frozenset({"AUTO", "GUIDED", "LOITER", "RTL", "BRAKE"})  # Mode::requires_GPS
ARMABLE = frozenset({"STABILIZE", "ALT_HOLD", "GUIDED", "LOITER"})  # Mode::allows_arming (from a GCS)
AUTOPILOT_MODES = frozenset({"AUTO", "GUIDED", "RTL", "LAND"})  # Mode::is_autopilot
USER_TAKEOFF = frozenset({"GUIDED", "LOITER"})  # Mode::has_user_takeoff(must_navigate=true)
STICK_MODES = frozenset({"STABILIZE", "ALT_HOLD"})  # manual attitude/throttle: no sticks here


class CopterState(Protocol):
    """What ardupilot_commands.py and ardupilot_telemetry.py read of the ArduPilot dialect."""

    ekf_delay_s: float
    gcs_failsafe: bool
    takeoff_z: float | None

    def position_ok(self, t: float, fix: Any) -> bool: ...

    def attitude_ok(self, t: float) -> bool: ...

    def unix_usec(self, t: float) -> int: ...

    def custom_mode(self, mode: str) -> int: ...

    def change_mode(self, v: Any, number: int) -> int: ...

    def polygon_fence_on(self, v: Any) -> bool: ...

    def polygon_allows(self, v: Any, ned: Any) -> bool: ...

    def default_rates(self) -> dict[int, float]: ...
