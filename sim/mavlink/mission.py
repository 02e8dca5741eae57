"""The MAVLink mission protocol from the vehicle's side: upload (COUNT -> REQUEST_INT... ->
ACK), download (REQUEST_LIST -> COUNT, REQUEST_INT -> ITEM_INT), clear and set-current.
Only the plain mission type is stored; fence and rally plans are answered honestly as
unsupported (upload) or empty (download)."""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

SUPPORTED = {
    mavlink.MAV_CMD_NAV_TAKEOFF,
    mavlink.MAV_CMD_NAV_WAYPOINT,
    mavlink.MAV_CMD_NAV_LAND,
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    mavlink.MAV_CMD_DO_CHANGE_SPEED,
}
FRAMES = {
    mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_INT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink.MAV_FRAME_MISSION,
}


@dataclass(frozen=True)
class MissionItem:
    seq: int
    frame: int
    command: int
    params: tuple[float, float, float, float]
    x: int  # lat * 1e7
    y: int  # lon * 1e7
    z: float  # altitude (frame-dependent)
    autocontinue: int = 1

    @classmethod
    def from_msg(cls, m) -> MissionItem:
        if m.get_type() == "MISSION_ITEM":  # float lat/lon
            x, y = int(round(m.x * 1e7)), int(round(m.y * 1e7))
        else:
            x, y = m.x, m.y
        return cls(m.seq, m.frame, m.command, (m.param1, m.param2, m.param3, m.param4), x, y, m.z, m.autocontinue)


class MissionStore:
    def __init__(self) -> None:
        self.items: list[MissionItem] = []
        self.current = 0
        # upload in progress: (expected count, received items, partner (sys, comp))
        self.incoming: list[MissionItem | None] | None = None
        self.partner: tuple[int, int] = (0, 0)
        self.last_request_t = 0.0
        self.retries = 0

    def validate(self, item: MissionItem, fence_ok) -> int:
        """MAV_MISSION_RESULT for one uploaded item; fence_ok(item) -> bool."""
        if item.command not in SUPPORTED:
            return mavlink.MAV_MISSION_UNSUPPORTED
        if item.frame not in FRAMES:
            return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
        if item.command in (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_TAKEOFF) and not fence_ok(item):
            return mavlink.MAV_MISSION_DENIED
        return mavlink.MAV_MISSION_ACCEPTED
