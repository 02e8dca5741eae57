"""MAVLink 2 framing without pymavlink's per-packet Python: the vehicle's hot path (issue 13).

pymavlink's `msg.pack(mav)` builds a header object, a bytearray and the CRC step by step, about
9 us a packet; a fleet of 100 vehicles sends ~9,000 packets per simulated second. Here the
payload comes from the message's own generated struct (once per message, shared by every link
that sends it), and each link adds its header and CRC with one `struct.pack` and one C CRC call.
Unsigned packets only: a signing link keeps pymavlink's packing (the signature needs its state).

The bytes are pymavlink's for the same sequence number (tests/sim/mavlink/test_wire.py).
"""

from __future__ import annotations

import struct

from pymavlink.dialects.v20 import common as mavlink

try:  # pymavlink's own fast CRC when installed (it is a pymavlink extra)
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover - CRC-16/MCRF4XX through binascii's CRC-CCITT, bit-reversed
    import binascii

    _REV = bytes(int(f"{i:08b}"[::-1], 2) for i in range(256))

    def _mcrf4xx(data: bytes, initial: int = 0xFFFF) -> int:
        def rev16(x: int) -> int:
            return (_REV[x & 0xFF] << 8) | _REV[x >> 8]

        return rev16(binascii.crc_hqx(data.translate(_REV), rev16(initial)))

_HEADER = struct.Struct("<BBBBBBBHB")  # STX, len, incompat, compat, seq, sysid, compid, msgid lo16, hi8
_CRC = struct.Struct("<H")
_STX = mavlink.PROTOCOL_MARKER_V2


def _grab(_mav: object, _crc_extra: int, payload: bytes, force_mavlink1: bool = False) -> bytes:
    return payload


def payload(msg: mavlink.MAVLink_message) -> bytes:
    """The message's MAVLink 2 payload (trailing zeros stripped, at least one byte), from the
    struct pymavlink generated for it: its `pack` hands the payload to `_pack`, caught here."""
    msg._pack = _grab  # an instance attribute: only this message object is affected
    try:
        raw = msg.pack(None)
    finally:
        del msg._pack
    body = raw.rstrip(b"\0")
    return body if body else raw[:1]


def frame(msg: mavlink.MAVLink_message, body: bytes, seq: int, sysid: int, compid: int) -> bytes:
    """One unsigned MAVLink 2 packet of `msg` with payload `body` (from `payload(msg)`)."""
    msgid = msg._header.msgId  # not msg.id: BATTERY_STATUS has a field called id
    head = _HEADER.pack(_STX, len(body), 0, 0, seq, sysid, compid, msgid & 0xFFFF, msgid >> 16)
    crc = _mcrf4xx(head[1:] + body + bytes((msg.crc_extra,)), 0xFFFF)
    return head + body + _CRC.pack(crc)
