"""PX4 flight modes as PX4 encodes them in HEARTBEAT.custom_mode (px4_custom_mode.h):
custom_mode = (sub_mode << 24) | (main_mode << 16)."""

from __future__ import annotations

MAIN_MODES = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6, "STABILIZED": 7}
AUTO_SUB_MODES = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}


def px4_custom_mode(name: str) -> int:
    main, _, sub = name.partition(".")
    return (AUTO_SUB_MODES.get(sub, 0) << 24) | (MAIN_MODES[main] << 16)


def px4_mode_name(main: int, sub: int) -> str | None:
    """(main, sub) as sent in DO_SET_MODE -> our mode name, or None if we do not fly it."""
    m = {v: k for k, v in MAIN_MODES.items()}.get(int(main))
    if m is None:
        return None
    if m != "AUTO":
        return m
    s = {v: k for k, v in AUTO_SUB_MODES.items()}.get(int(sub))
    return f"AUTO.{s}" if s else None
