"""MAVLink 2 signing checks for the vehicle, stricter than pymavlink's own.

pymavlink records a stream's timestamp before it checks the signature, keeps one table per
link, and lets any timestamp raise its clock. So one forged packet carrying the largest
timestamp locked the legitimate sender out for good, and a signed command seen on one link
could be replayed onto the other. Here, on every link of one vehicle:
- the signature is checked first: an unsigned or badly signed packet changes nothing;
- one replay table (link id, system, component) -> last timestamp serves all links, so a packet
  accepted on one link is a replay on every other;
- a timestamp more than MAX_AHEAD_S ahead of the vehicle's signing clock is refused (a
  sender's clock may run a little fast; far ahead is a forgery or a broken clock);
- a new stream may start at most NEW_STREAM_BEHIND_S behind the clock (the spec's minute).
The vehicle's own signing clock follows wall time (signing_timestamp), never a value frozen at
start, so a client joining later accepts its packets."""

from __future__ import annotations

import hashlib
import struct
import threading

from pymavlink.dialects.v20 import common as mavlink

from .udp import signing_timestamp

MAX_AHEAD_S = 60.0
NEW_STREAM_BEHIND_S = 60.0
UNITS_PER_S = 100_000  # the signing timestamp counts 10 us


class SigningGuard:
    """One per vehicle, installed on each of its links' MAVLink objects."""

    def __init__(self, key: bytes) -> None:
        if len(key) != 32:
            raise ValueError("a MAVLink2 signing key is 32 bytes")
        self.key = key
        self.streams: dict[tuple[int, int, int], int] = {}
        self.refused = {"signature": 0, "replay": 0, "ahead": 0, "stale_stream": 0}
        self._lock = threading.Lock()

    def install(self, mav: mavlink.MAVLink) -> None:
        mav.check_signature = lambda msgbuf, src, comp: self.check(mav, msgbuf, src, comp)

    def check(self, mav: mavlink.MAVLink, msgbuf: bytearray, src: int, comp: int) -> bool:
        sig = hashlib.sha256(self.key + bytes(msgbuf[:-6])).digest()[:6]
        if sig != bytes(msgbuf[-6:]):
            self.refused["signature"] += 1
            return False
        link_id = msgbuf[-13]
        tlow, thigh = struct.unpack("<IH", bytes(msgbuf[-12:-6]))
        ts = tlow + (thigh << 32)
        now = signing_timestamp()
        if ts > now + MAX_AHEAD_S * UNITS_PER_S:
            self.refused["ahead"] += 1
            return False
        key = (link_id, src, comp)
        with self._lock:
            last = self.streams.get(key)
            if last is None and ts + NEW_STREAM_BEHIND_S * UNITS_PER_S < now:
                self.refused["stale_stream"] += 1
                return False
            if last is not None and ts <= last:
                self.refused["replay"] += 1
                return False
            self.streams[key] = ts
        mav.signing.timestamp = max(mav.signing.timestamp, ts)
        return True
