"""The MAVLink mission protocol for MAV_MISSION_TYPE_FENCE, from the vehicle's side, as each
autopilot family answers it (their ACK results and STATUSTEXTs word for word):

- PX4 (src/modules/mavlink/mavlink_mission.cpp, MavlinkMissionManager, main 2026-08): at most
  64 items (DM_KEY_FENCE_POINTS_MAX) else NO_SPACE; COUNT 0 clears; items are asked for with
  MISSION_REQUEST_INT, again every 0.25 s, and the upload is dropped 5 s after the last message
  ("Mission sync timeout", no ACK); an item out of order is ignored; a bad frame is
  UNSUPPORTED_FRAME, a parameter the command does not use that is neither 0 nor NaN is
  INVALID_PARAMn (mavlink_command_params.hpp: fence items use param 1 and x/y only, so z must
  be 0), a polygon vertex with a vertex count below 3 is ERROR; each ends the upload. The last
  item sent again after the ACK is ACKed again. Stored, the fence is loaded as
  Geofence::_updateFence does (polyfence.px4_zones, its home and position checks); read back,
  every item is in GLOBAL_INT. Its STATUSTEXTs keep the trailing tab PX4 sends (the mark of a
  text that also goes out as an event), as the real SITL was seen to.
- ArduCopter (libraries/GCS_MAVLink/MissionItemProtocol.cpp, MissionItemProtocol_Fence.cpp,
  2024-05): at most 70 items on SITL (fence storage / 8 bytes: "Only 70 items are
  supported", NO_SPACE); a COUNT from another station during an upload is DENIED, from the same
  restarts it; items are asked for with MISSION_REQUEST (not _INT), again every 1 s, and the
  upload is cancelled 8 s after the last item ("Fence upload timeout", ACK
  OPERATION_CANCELLED); an item out of order is INVALID_SEQUENCE (the upload goes on); a bad
  frame is UNSUPPORTED_FRAME, a non-fence command UNSUPPORTED (each ends it); the whole upload
  is validated at its end (AC_PolyFence_loader::validate_fence: its STATUSTEXT, "Fence
  validation failed", ERROR). Downloads carry frame 0 and z 0, as its get_item leaves them.

Re-requests and timeouts run on wall-clock time, as the mission protocol's (mission.py).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any, Protocol

from pymavlink.dialects.v20 import common as mavlink

from .polyfence import (
    CIRCLES,
    POLYGONS,
    RETURN_POINT,
    FenceItem,
    Zone,
    ardupilot_validate,
    ardupilot_zones,
    px4_zone_passes,
    px4_zones,
)

M = mavlink
FENCE = M.MAV_MISSION_TYPE_FENCE
FENCE_COMMANDS = POLYGONS | CIRCLES | {RETURN_POINT}
#: commands PX4's parser takes in a global frame (others: UNSUPPORTED); in a fence upload the
#: mission ones are stored and then skipped by the geofence ("unhandled Fence command")
PX4_PARSED = FENCE_COMMANDS | {M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_CMD_NAV_LOITER_TIME,
                               M.MAV_CMD_NAV_LAND, M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_RALLY_POINT}
PX4_GLOBAL = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_RELATIVE_ALT})
PX4_GLOBAL_INT = frozenset({M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})
AP_FRAMES = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                       M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL_TERRAIN_ALT,
                       M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT})


class FenceStore:
    """The vehicle's fence: the items as stored (for download), the zones it enforces, and the
    enforcement's state (dialects/ run it)."""

    def __init__(self) -> None:
        self.items: list[FenceItem] = []
        self.zones: list[Zone] = []
        self.breached = False  # outside the polygon fence at its last check
        self.next_check_t = 0.0  # simulated time of the next breach check
        self.uploads = 0  # fences stored (count-0 clears included)


class FenceHost(Protocol):
    """What the fence protocol needs from the vehicle."""

    fences: FenceStore
    params: Any
    home: Any
    model: Any

    @property
    def mav(self) -> mavlink.MAVLink: ...

    def send(self, msg: Any) -> None: ...

    def statustext(self, text: str, severity: int = ...) -> None: ...

    def estimate(self) -> Any: ...


def _unset(v: float) -> bool:
    """mavlink_command_params::param_is_unset: NaN or +-0."""
    return math.isnan(v) or v == 0.0


class FenceProtocol:
    """What both families share: routing, the sender's address, ACKs and item messages."""

    def __init__(self, host: FenceHost, clock: Callable[[], float] = time.monotonic) -> None:
        self.host, self.clock = host, clock
        self.incoming: list[FenceItem | None] | None = None  # an upload under way
        self.partner: tuple[int, int] | None = None
        self.last_recv = self.last_sent = 0.0
        self._warned: set[str] = set()

    def handle(self, msg: mavlink.MAVLink_message) -> None:
        kind = msg.get_type()
        if kind == "MISSION_COUNT":
            self.on_count(msg)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self.on_item(msg)
        elif kind == "MISSION_REQUEST_LIST":
            self.on_request_list(msg)
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self.on_request(msg)
        elif kind == "MISSION_CLEAR_ALL":
            self.on_clear(msg)
        # MISSION_ACK ends a download: nothing to do

    @staticmethod
    def src(msg: mavlink.MAVLink_message) -> tuple[int, int]:
        return msg.get_srcSystem(), msg.get_srcComponent()

    def ack(self, to: tuple[int, int], result: int) -> None:
        self.host.send(self.host.mav.mission_ack_encode(*to, result, FENCE))

    def send_item(self, to: tuple[int, int], it: FenceItem, as_int: bool) -> None:
        mav = self.host.mav
        if as_int:
            self.host.send(mav.mission_item_int_encode(*to, it.seq, it.frame, it.command, 0, 0, it.param1, 0, 0, 0,
                                                       it.x, it.y, it.z, FENCE))
        else:
            self.host.send(mav.mission_item_encode(*to, it.seq, it.frame, it.command, 0, 0, it.param1, 0, 0, 0,
                                                   it.x * 1e-7, it.y * 1e-7, it.z, FENCE))

    def warn_once(self, text: str, severity: int = M.MAV_SEVERITY_WARNING) -> None:
        if text not in self._warned:
            self._warned.add(text)
            self.host.statustext(text, severity)

    def store(self, items: list[FenceItem]) -> None:
        f = self.host.fences
        f.items, f.zones, f.breached, f.uploads = items, self.load(items), False, f.uploads + 1

    def clear(self) -> None:
        self.store([])

    # each family's
    def load(self, items: list[FenceItem]) -> list[Zone]:
        raise NotImplementedError

    def on_count(self, msg: mavlink.MAVLink_message) -> None:
        raise NotImplementedError

    def on_item(self, msg: mavlink.MAVLink_message) -> None:
        raise NotImplementedError

    def on_request_list(self, msg: mavlink.MAVLink_message) -> None:
        raise NotImplementedError

    def on_request(self, msg: mavlink.MAVLink_message) -> None:
        raise NotImplementedError

    def on_clear(self, msg: mavlink.MAVLink_message) -> None:
        raise NotImplementedError

    def poll(self) -> None:
        raise NotImplementedError


def _lat_lon_e7(msg: mavlink.MAVLink_message) -> tuple[int, int] | None:
    """x, y in 1e-7 degrees (MISSION_ITEM's float degrees converted); None: not finite."""
    x, y = float(msg.x), float(msg.y)
    if msg.get_type() == "MISSION_ITEM":
        x, y = x * 1e7, y * 1e7
    if not (math.isfinite(x) and math.isfinite(y) and abs(x) < 2**31 and abs(y) < 2**31):
        return None
    return int(round(x)), int(round(y))


class Px4FenceProtocol(FenceProtocol):
    MAX_ITEMS = 64  # DM_KEY_FENCE_POINTS_MAX
    RETRY_S = 0.25  # MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT
    TIMEOUT_S = 5.0  # MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT

    def __init__(self, host: FenceHost, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(host, clock)
        self.transfer_seq = 0  # the next item expected (upload) or sent (download)

    def _request(self) -> None:
        assert self.partner is not None
        self.host.send(self.host.mav.mission_request_int_encode(*self.partner, self.transfer_seq, FENCE))
        self.last_sent = self.clock()

    def _critical(self, text: str) -> None:
        self.host.statustext(text, M.MAV_SEVERITY_CRITICAL)

    def on_count(self, msg: mavlink.MAVLink_message) -> None:
        src = self.src(msg)
        if self.incoming is not None:  # MAVLINK_WPM_STATE_GETLIST
            self.last_recv = self.clock()
            if src != self.partner:
                return self.ack(src, M.MAV_MISSION_ERROR)
            if self.transfer_seq == 0:
                return self._request()  # "looks like our MISSION_REQUEST was lost, try again"
            self._critical("WPM: REJ. CMD: Busy\t")
            return self.ack(src, M.MAV_MISSION_ERROR)
        self.partner = src
        if msg.count > self.MAX_ITEMS:
            return self.ack(src, M.MAV_MISSION_NO_SPACE)
        if msg.count == 0:
            self.clear()
            return self.ack(src, M.MAV_MISSION_ACCEPTED)
        self.incoming, self.transfer_seq, self.last_recv = [None] * msg.count, 0, self.clock()
        self._request()
        return None

    def _parse(self, msg: mavlink.MAVLink_message) -> FenceItem | int:
        """parse_mavlink_mission_item for a fence upload: the item or its MAV_MISSION_RESULT."""
        as_int = msg.get_type() == "MISSION_ITEM_INT"
        frame, cmd = msg.frame, msg.command
        global_frame = frame in PX4_GLOBAL or (as_int and frame in PX4_GLOBAL_INT)
        if not global_frame and frame != M.MAV_FRAME_MISSION:
            return M.MAV_MISSION_UNSUPPORTED_FRAME
        if cmd in FENCE_COMMANDS:  # the params table: 5000 uses x, y, z; 5001-5004 param 1, x, y
            uses_z = cmd == RETURN_POINT
            for k, v in enumerate((msg.param1, msg.param2, msg.param3, msg.param4)):
                if (k > 0 or cmd == RETURN_POINT) and not _unset(float(v)):
                    return M.MAV_MISSION_INVALID_PARAM1 + k
            if not uses_z and not _unset(float(msg.z)):
                return M.MAV_MISSION_INVALID_PARAM7
        if not global_frame or cmd not in PX4_PARSED:
            return M.MAV_MISSION_UNSUPPORTED
        xy = _lat_lon_e7(msg)
        if xy is None:
            return M.MAV_MISSION_INVALID_PARAM5_X
        return FenceItem(msg.seq, frame, cmd, float(msg.param1), xy[0], xy[1], float(msg.z))

    def on_item(self, msg: mavlink.MAVLink_message) -> None:
        src = self.src(msg)
        if self.partner is not None and src != self.partner:
            return self._critical("REJ. MIS ITEM: partner id mismatch\t")
        inc = self.incoming
        if inc is None:  # MAVLINK_WPM_STATE_IDLE
            if self.partner is not None and self.transfer_seq == msg.seq + 1:
                return self.ack(src, M.MAV_MISSION_ACCEPTED)  # our ACK was lost: the same again
            self._critical("IGN MISSION_ITEM: No transfer\t")
            return self.ack(src, M.MAV_MISSION_ERROR)
        self.last_recv = self.clock()
        if msg.seq != self.transfer_seq:
            return None  # "Item sequence not expected, ignore item"
        item = self._parse(msg)
        if isinstance(item, int):
            self._critical("IGN MISSION_ITEM: Invalid item\t")
            self.incoming = None
            return self.ack(src, item)
        if item.command in POLYGONS and int(item.param1 + 0.5) < 3:  # "Fence: too few vertices"
            self.incoming = None
            return self.ack(src, M.MAV_MISSION_ERROR)
        inc[msg.seq] = item
        self.transfer_seq = msg.seq + 1
        if self.transfer_seq < len(inc):
            return self._request()
        self.incoming = None
        self.store([x for x in inc if x is not None])
        self.ack(src, M.MAV_MISSION_ACCEPTED)
        return None

    def load(self, items: list[FenceItem]) -> list[Zone]:
        """Geofence::_updateFence with checkHomeRequirementsForGeofence and
        checkCurrentPositionRequirementsForGeofence: a zone failing either is dropped."""
        h = self.host
        kept = []
        flying = h.params["GF_ACTION"] != 0 and not h.model.state.landed
        if flying:
            lat, lon, _ = h.home.ned_to_geodetic(h.estimate())
        for z in px4_zones(items):
            if not px4_zone_passes(z, h.home.lat_deg, h.home.lon_deg):
                self._critical("Geofence invalid, doesn't contain Home position\t")
            elif flying and not px4_zone_passes(z, lat, lon):
                self._critical("Geofence invalid, doesn't contain current vehicle position\t")
            else:
                kept.append(z)
        return kept

    def on_request_list(self, msg: mavlink.MAVLink_message) -> None:
        if self.incoming is not None:  # no ACK: "ignored"
            return self.host.statustext("Mission download request ignored, already active\t", M.MAV_SEVERITY_INFO)
        self.partner, self.transfer_seq = self.src(msg), 0
        self.host.send(self.host.mav.mission_count_encode(*self.src(msg), len(self.host.fences.items), FENCE))
        return None

    def on_request(self, msg: mavlink.MAVLink_message) -> None:
        if self.incoming is not None:  # MAVLINK_WPM_STATE_GETLIST
            return self._critical("WPM: REJ. CMD: Busy\t")
        items = self.host.fences.items
        if not 0 <= msg.seq < len(items):
            self._critical("WPM: REJ. CMD: Req. WP was unexpected\t")
            return self.ack(self.src(msg), M.MAV_MISSION_ERROR)
        self.transfer_seq = msg.seq + 1
        as_int = msg.get_type() == "MISSION_REQUEST_INT"
        # format_mavlink_mission_item: a fence point has no relative altitude, so it goes out in
        # GLOBAL_INT (GLOBAL to MISSION_REQUEST) whatever frame it came in (measured: 0 -> 5)
        it = replace(items[msg.seq], frame=M.MAV_FRAME_GLOBAL_INT if as_int else M.MAV_FRAME_GLOBAL)
        self.send_item(self.src(msg), it, as_int)
        return None

    def on_clear(self, msg: mavlink.MAVLink_message) -> None:
        if self.incoming is not None:
            self._critical("WPM: IGN CLEAR CMD: Busy\t")
            return self.ack(self.src(msg), M.MAV_MISSION_ERROR)
        self.clear()
        return self.ack(self.src(msg), M.MAV_MISSION_ACCEPTED)

    def poll(self) -> None:
        if self.incoming is None:
            return
        now = self.clock()
        if now - self.last_recv > self.TIMEOUT_S:
            self._critical("Mission sync timeout\t")
            self.incoming = None
        elif now - self.last_sent > self.RETRY_S:
            self._request()


class ArduPilotFenceProtocol(FenceProtocol):
    MAX_ITEMS = 70  # AC_PolyFence_loader::max_items on SITL: fence storage / sizeof(Vector2l)
    RETRY_S = 1.0  # MissionItemProtocol::update: 1000 ms + the link's stream slowdown
    TIMEOUT_S = 8.0  # upload_timeout_ms

    def __init__(self, host: FenceHost, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(host, clock)
        self.request_i = 0

    def _request(self) -> None:
        assert self.partner is not None
        self.host.send(self.host.mav.mission_request_encode(*self.partner, self.request_i, FENCE))
        self.last_sent = self.clock()

    def _end(self) -> None:
        self.incoming = None

    def on_count(self, msg: mavlink.MAVLink_message) -> None:
        src = self.src(msg)
        if self.incoming is not None and src != self.partner:
            return self.ack(src, M.MAV_MISSION_DENIED)
        if msg.count > self.MAX_ITEMS:
            self.ack(src, M.MAV_MISSION_NO_SPACE)
            self.host.statustext(f"Only {self.MAX_ITEMS} items are supported", M.MAV_SEVERITY_WARNING)
            return None
        self.partner = src
        if msg.count == 0:
            self._end()
            return self._complete(src, [])
        self.incoming, self.request_i = [None] * msg.count, 0
        self.last_recv = self.clock()
        self._request()
        return None

    def on_item(self, msg: mavlink.MAVLink_message) -> None:
        src = self.src(msg)
        if msg.get_type() == "MISSION_ITEM":
            self.warn_once("got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
        inc = self.incoming
        if inc is None:
            return self.ack(src, M.MAV_MISSION_ERROR)
        if msg.seq != self.request_i:
            return self.ack(src, M.MAV_MISSION_INVALID_SEQUENCE)
        if src != self.partner:
            return self.ack(src, M.MAV_MISSION_DENIED)
        result = M.MAV_MISSION_ACCEPTED
        xy = _lat_lon_e7(msg)
        if msg.frame not in AP_FRAMES:
            result = M.MAV_MISSION_UNSUPPORTED_FRAME
        elif msg.command not in FENCE_COMMANDS:
            result = M.MAV_MISSION_UNSUPPORTED
        elif xy is None:
            result = M.MAV_MISSION_INVALID_PARAM5_X
        if result != M.MAV_MISSION_ACCEPTED:
            self._end()
            return self.ack(src, result)
        assert xy is not None
        # stored as AC_PolyFenceItem: no frame, no altitude
        inc[msg.seq] = FenceItem(msg.seq, M.MAV_FRAME_GLOBAL, msg.command, float(msg.param1), xy[0], xy[1], 0.0)
        self.last_recv = self.clock()
        self.request_i += 1
        if self.request_i < len(inc):
            return self._request()
        self._end()
        return self._complete(src, [x for x in inc if x is not None])

    def _complete(self, src: tuple[int, int], items: list[FenceItem]) -> None:
        """MissionItemProtocol_Fence::complete -> AC_PolyFence_loader::write_fence."""
        why = ardupilot_validate(items)
        if why is not None:
            self.host.statustext(why, M.MAV_SEVERITY_WARNING)
            self.host.statustext("Fence validation failed", M.MAV_SEVERITY_WARNING)
            return self.ack(src, M.MAV_MISSION_ERROR)
        self.store(items)
        self.host.statustext("Fence Indexed OK", M.MAV_SEVERITY_DEBUG)  # index_eeprom, after the write
        return self.ack(src, M.MAV_MISSION_ACCEPTED)

    def load(self, items: list[FenceItem]) -> list[Zone]:
        return ardupilot_zones(items)

    def on_request_list(self, msg: mavlink.MAVLink_message) -> None:
        if self.incoming is not None:
            return self.ack(self.src(msg), M.MAV_MISSION_DENIED)
        self.host.send(self.host.mav.mission_count_encode(*self.src(msg), len(self.host.fences.items), FENCE))
        return None

    def on_request(self, msg: mavlink.MAVLink_message) -> None:
        src = self.src(msg)
        if self.incoming is not None:
            return self.ack(src, M.MAV_MISSION_DENIED)
        items = self.host.fences.items
        if msg.seq > len(items):
            return self.ack(src, M.MAV_MISSION_INVALID_SEQUENCE)
        if msg.seq == len(items):
            return self.ack(src, M.MAV_MISSION_ERROR)  # get_item fails one past the end
        as_int = msg.get_type() == "MISSION_REQUEST_INT"
        if not as_int:
            self.warn_once("got MISSION_REQUEST; use MISSION_REQUEST_INT!")
        self.send_item(src, items[msg.seq], as_int)
        return None

    def on_clear(self, msg: mavlink.MAVLink_message) -> None:
        if self.incoming is not None:
            return self.ack(self.src(msg), M.MAV_MISSION_ERROR)
        self.clear()
        self.host.statustext("Fence Indexed OK", M.MAV_SEVERITY_DEBUG)
        return self.ack(self.src(msg), M.MAV_MISSION_ACCEPTED)

    def poll(self) -> None:
        if self.incoming is None or self.partner is None:
            return
        now = self.clock()
        if now - self.last_recv > self.TIMEOUT_S:
            self._end()
            self.host.statustext("Fence upload timeout", M.MAV_SEVERITY_WARNING)
            self.ack(self.partner, M.MAV_MISSION_OPERATION_CANCELLED)
        elif now - self.last_sent > self.RETRY_S:
            self._request()
