"""PX4 flight modes as the autopilot encodes them in HEARTBEAT.custom_mode:
custom_mode = (sub_mode << 24) | (main_mode << 16) (PX4's px4_custom_mode.h)."""

from __future__ import annotations

MAIN = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6, "STABILIZED": 7}
AUTO_SUB = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}


def encode(name: str) -> tuple[int, int]:
    """'AUTO.LOITER' -> (main, sub); 'OFFBOARD' -> (6, 0)."""
    main, _, sub = name.upper().partition(".")
    if main not in MAIN or (sub and (main != "AUTO" or sub not in AUTO_SUB)):
        known = list(MAIN) + [f"AUTO.{s}" for s in AUTO_SUB]
        raise ValueError(f"unknown PX4 mode {name!r}; known: {known}")
    return MAIN[main], AUTO_SUB.get(sub, 0)


def custom_mode(name: str) -> int:
    main, sub = encode(name)
    return (sub << 24) | (main << 16)


def decode(custom: int) -> str:
    main, sub = (custom >> 16) & 0xFF, (custom >> 24) & 0xFF
    mname = next((k for k, v in MAIN.items() if v == main), f"MAIN{main}")
    if mname == "AUTO":
        return "AUTO." + next((k for k, v in AUTO_SUB.items() if v == sub), f"SUB{sub}")
    return mname
