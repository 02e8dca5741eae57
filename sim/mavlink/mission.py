"""The MAVLink mission protocol from the vehicle's side: upload (COUNT -> REQUEST_INT... ->
ACK), download (REQUEST_LIST -> COUNT, REQUEST_INT -> ITEM_INT), clear and set-current.
The plain mission type is stored here; fence transfers go to the dialect's fence protocol
(fence_protocol.py) when the vehicle has one; rally plans are answered honestly as
unsupported (upload) or empty (download). Re-requests run on wall-clock time: the ground
station answers in its time, not the simulation's (which may run hundreds of times faster)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from pymavlink.dialects.v20 import common as mavlink

SUPPORTED = {
    mavlink.MAV_CMD_NAV_TAKEOFF,
    mavlink.MAV_CMD_NAV_WAYPOINT,
    mavlink.MAV_CMD_NAV_LAND,
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    mavlink.MAV_CMD_DO_CHANGE_SPEED,
}
#: items whose params 5-7 are a position the vehicle flies to
POSITIONAL = frozenset({mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_WAYPOINT})
FRAMES = {
    mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_INT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink.MAV_FRAME_MISSION,
}


MAX_ITEMS = 500  # what this vehicle stores; more is MAV_MISSION_NO_SPACE


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
    def from_msg(cls, m) -> MissionItem | int:
        """The item, or the MAV_MISSION_RESULT that refuses it (NaN, inf or out-of-range
        position: a hostile or broken sender gets an error ACK, never a traceback)."""
        x, y, z = float(m.x), float(m.y), float(m.z)
        if m.get_type() == "MISSION_ITEM":  # float lat/lon in degrees
            x, y = x * 1e7, y * 1e7
        if m.command not in POSITIONAL:  # params 5-7 are not a position (NaN: unused)
            x, y = (v if math.isfinite(v) and abs(v) < 2**31 else 0.0 for v in (x, y))
        elif not (math.isfinite(x) and abs(x) <= 90e7):
            return mavlink.MAV_MISSION_INVALID_PARAM5_X
        elif not (math.isfinite(y) and abs(y) <= 180e7):
            return mavlink.MAV_MISSION_INVALID_PARAM6_Y
        elif not (math.isfinite(z) and abs(z) <= 1e5):
            return mavlink.MAV_MISSION_INVALID_PARAM7
        return cls(m.seq, m.frame, m.command, (m.param1, m.param2, m.param3, m.param4), int(round(x)), int(round(y)),
                   z, m.autocontinue)


class MissionStore:
    """The stored mission and the item being flown."""

    def __init__(self) -> None:
        self.items: list[MissionItem] = []
        self.current = 0


def validate(item: MissionItem, fence_ok: Callable[[MissionItem], bool]) -> int:
    """MAV_MISSION_RESULT for one uploaded item."""
    if item.command not in SUPPORTED:
        return mavlink.MAV_MISSION_UNSUPPORTED
    if item.frame not in FRAMES:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    if item.command in (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_TAKEOFF) and not fence_ok(item):
        return mavlink.MAV_MISSION_DENIED
    return mavlink.MAV_MISSION_ACCEPTED


class MissionHost(Protocol):
    """What the protocol needs from the vehicle."""

    @property
    def mav(self) -> mavlink.MAVLink: ...

    def send(self, msg: mavlink.MAVLink_message) -> None: ...

    def statustext(self, text: str, severity: int = ...) -> None: ...

    def mission_item_allowed(self, item: MissionItem) -> bool:
        """Inside the geofence (and say so when not)."""

    def mission_running(self) -> bool:
        """Flying the stored mission now: it may not be replaced."""

    def mission_changed(self, cleared: bool) -> None:
        """The stored mission or its current item changed under the vehicle."""

    def send_mission_current(self) -> None: ...


def _mission_type(msg: mavlink.MAVLink_message) -> int:
    return getattr(msg, "mission_type", mavlink.MAV_MISSION_TYPE_MISSION)


class MissionProtocol:
    RETRY_S = 0.5  # wall-clock seconds before an item is requested again
    MAX_RETRIES = 10

    def __init__(self, host: MissionHost, store: MissionStore, clock: Callable[[], float] = time.monotonic) -> None:
        self.host, self.store, self.clock = host, store, clock
        self.incoming: list[MissionItem | None] | None = None  # an upload under way
        self.partner: tuple[int, int] = (0, 0)  # who is uploading (system, component)
        self.last_request_t = 0.0
        self.retries = 0
        self.completed: tuple[tuple[int, int], int] | None = None  # (partner, count) of the last upload
        #: MAV_MISSION_TYPE_FENCE transfers (fence_protocol.py; None: answered as unsupported)
        self.fences = None

    HANDLES = frozenset({"MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_REQUEST_LIST",
                         "MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
                         "MISSION_ACK"})

    def handle(self, msg: mavlink.MAVLink_message) -> None:
        kind = msg.get_type()
        if self.fences is not None and kind != "MISSION_SET_CURRENT":
            mtype = _mission_type(msg)
            if mtype == mavlink.MAV_MISSION_TYPE_FENCE:
                return self.fences.handle(msg)
            if kind == "MISSION_CLEAR_ALL" and mtype == mavlink.MAV_MISSION_TYPE_ALL:
                self.fences.clear()  # and the mission, below, which ACKs once
        if kind == "MISSION_COUNT":
            self._on_count(msg)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self._on_item(msg)
        elif kind == "MISSION_REQUEST_LIST":
            mtype = _mission_type(msg)
            n = len(self.store.items) if mtype == mavlink.MAV_MISSION_TYPE_MISSION else 0
            self.host.send(self.host.mav.mission_count_encode(msg.get_srcSystem(), msg.get_srcComponent(), n, mtype))
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._on_request(msg)
        elif kind == "MISSION_CLEAR_ALL":
            if _mission_type(msg) in (mavlink.MAV_MISSION_TYPE_MISSION, mavlink.MAV_MISSION_TYPE_ALL):
                self.store.items, self.store.current = [], 0
                self.host.mission_changed(cleared=True)
            self._ack(msg, mavlink.MAV_MISSION_ACCEPTED, _mission_type(msg))
        elif kind == "MISSION_SET_CURRENT":
            if 0 <= msg.seq < len(self.store.items):
                self.store.current = msg.seq
                self.host.mission_changed(cleared=False)
            self.host.send_mission_current()
        # MISSION_ACK ends a download: nothing to do
        return None

    def _ack(self, msg: mavlink.MAVLink_message, result: int, mission_type: int = 0) -> None:
        self.host.send(self.host.mav.mission_ack_encode(msg.get_srcSystem(), msg.get_srcComponent(), result,
                                                        mission_type))

    def _request(self, seq: int) -> None:
        sysid, comp = self.partner
        self.host.send(self.host.mav.mission_request_int_encode(sysid, comp, seq, 0))
        self.last_request_t = self.clock()

    def _on_count(self, msg: mavlink.MAVLink_message) -> None:
        mtype = _mission_type(msg)
        if mtype != mavlink.MAV_MISSION_TYPE_MISSION:
            return self._ack(msg, mavlink.MAV_MISSION_UNSUPPORTED, mtype)
        if self.host.mission_running():
            self.host.statustext("Mission upload denied: flying the mission", mavlink.MAV_SEVERITY_WARNING)
            return self._ack(msg, mavlink.MAV_MISSION_DENIED)
        if msg.count > MAX_ITEMS:
            return self._ack(msg, mavlink.MAV_MISSION_NO_SPACE)
        self.partner = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.count == 0:
            self.store.items, self.store.current = [], 0
            self.host.mission_changed(cleared=True)
            return self._ack(msg, mavlink.MAV_MISSION_ACCEPTED)
        self.incoming = [None] * msg.count
        self.completed = None
        self.retries = 0
        self._request(0)
        return None

    def _on_item(self, msg: mavlink.MAVLink_message) -> None:
        inc = self.incoming
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if inc is None and self.completed == (src, msg.seq + 1) and _mission_type(msg) == mavlink.MAV_MISSION_TYPE_MISSION:
            # the last item again: our ACK was lost and the station resends it (MAVLink's mission
            # protocol); the upload is done, say so again
            return self._ack(msg, mavlink.MAV_MISSION_ACCEPTED)
        if inc is None or _mission_type(msg) != mavlink.MAV_MISSION_TYPE_MISSION:
            return
        if src != self.partner:
            return  # another station's item in the middle of this upload
        if not 0 <= msg.seq < len(inc):
            self.incoming = None
            return self._ack(msg, mavlink.MAV_MISSION_INVALID_SEQUENCE)
        item = MissionItem.from_msg(msg)
        if isinstance(item, int):
            self.incoming = None
            self.host.statustext(f"Mission item {msg.seq} refused: position not finite or out of range",
                                 mavlink.MAV_SEVERITY_WARNING)
            return self._ack(msg, item)
        result = validate(item, self.host.mission_item_allowed)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self.incoming = None
            return self._ack(msg, result)
        inc[msg.seq] = item
        missing = [i for i, x in enumerate(inc) if x is None]
        if missing:
            self.retries = 0
            return self._request(missing[0])
        self.store.items = [x for x in inc if x is not None]
        self.store.current = 0
        self.incoming = None
        self.completed = (self.partner, len(self.store.items))
        self.host.mission_changed(cleared=False)
        self._ack(msg, mavlink.MAV_MISSION_ACCEPTED)
        self.host.send_mission_current()
        return None

    def _on_request(self, msg: mavlink.MAVLink_message) -> None:
        if msg.seq >= len(self.store.items) or _mission_type(msg) != mavlink.MAV_MISSION_TYPE_MISSION:
            return self._ack(msg, mavlink.MAV_MISSION_INVALID_SEQUENCE)
        it = self.store.items[msg.seq]
        self.host.send(self.host.mav.mission_item_int_encode(
            msg.get_srcSystem(), msg.get_srcComponent(), it.seq, it.frame, it.command,
            int(it.seq == self.store.current), it.autocontinue, *it.params, it.x, it.y, it.z, 0))
        return None

    def poll(self) -> None:
        """Ask again for a missing item, or give the upload up."""
        if self.fences is not None:
            self.fences.poll()
        inc = self.incoming
        if inc is None or self.clock() - self.last_request_t < self.RETRY_S:
            return
        self.retries += 1
        if self.retries > self.MAX_RETRIES:
            # give up, and say so: the station must not wait for an ACK that never comes
            self.incoming = None
            self.host.statustext("Mission upload timed out", mavlink.MAV_SEVERITY_WARNING)
            self.host.send(self.host.mav.mission_ack_encode(*self.partner, mavlink.MAV_MISSION_OPERATION_CANCELLED,
                                                            mavlink.MAV_MISSION_TYPE_MISSION))
            return
        self._request(next(i for i, x in enumerate(inc) if x is None))
