"""MAVLink 2 framing without pymavlink's per-packet Python: the vehicle's hot path (issue 13).

pymavlink's `msg.pack(mav)` builds a header object, a bytearray and the CRC step by step, about
9 us a packet; a fleet of 100 vehicles sends ~9,000 packets per simulated second. Here the
payload comes from the message's own generated struct (once per message, shared by every link
that sends it), and each link adds its header and CRC with one `struct.pack` and one C CRC call.
Unsigned packets only: a signing link keeps pymavlink's packing (the signature needs its state).

The bytes are pymavlink's for the same sequence number (tests/sim/mavlink/test_wire.py).

`ENCODER` stands in for pymavlink's MAVLink object where the vehicle builds its telemetry: its
`<message>_encode(...)` takes the same arguments and returns a `Packed` (id, CRC extra, payload)
packed by the message's own generated struct, without the message object (its constructor and
`pack` cost more than the payload itself: 13 us a telemetry message in all, 45 a second per
vehicle).
"""

from __future__ import annotations

import inspect
import struct
from typing import Any, NamedTuple

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


class Packed(NamedTuple):
    """A message ready to frame: what the vehicle's hot path sends instead of a message object."""

    msg_id: int
    crc_extra: int
    body: bytes  # the MAVLink 2 payload, trailing zeros stripped (at least one byte)


def frame_packed(p: Packed, seq: int, sysid: int, compid: int) -> bytes:
    """One unsigned MAVLink 2 packet of a Packed message."""
    msgid, body = p.msg_id, p.body
    head = _HEADER.pack(_STX, len(body), 0, 0, seq, sysid, compid, msgid & 0xFFFF, msgid >> 16)
    return head + body + _CRC.pack(_mcrf4xx(head[1:] + body + bytes((p.crc_extra,)), 0xFFFF))


_EXTRA = [bytes((i,)) for i in range(256)]  # a CRC extra as the one byte the CRC reads


def frame_all(packets: list[Packed], seq: int, sysid: int, compid: int) -> list[bytes]:
    """frame_packed for consecutive packets numbered from seq, in one loop (a vehicle's tick of
    telemetry: no call per packet)."""
    out, pack, crc, crc_pack, extra = [], _HEADER.pack, _mcrf4xx, _CRC.pack, _EXTRA
    for msgid, crc_extra, body in packets:  # Packed, or a plain (id, CRC extra, payload) tuple
        head = pack(_STX, len(body), 0, 0, seq, sysid, compid, msgid & 0xFFFF, msgid >> 16)
        out.append(head + body + crc_pack(crc(head[1:] + body + extra[crc_extra], 0xFFFF)))
        seq = (seq + 1) & 0xFF
    return out


def _strip(raw: bytes) -> bytes:
    body = raw.rstrip(b"\0")
    return body if body else raw[:1]


def _encoder(name: str) -> Any:
    """`<message>_encode` for a Packed: pymavlink's encode method's signature (defaults and extension
    fields default as there), its payload struct fed in wire order with arrays spread, as its
    generated `pack` feeds it (char arrays go in whole, as bytes)."""
    cls = getattr(mavlink, f"MAVLink_{name[:-len('_encode')]}_message", None)
    if cls is None or not name.endswith("_encode"):
        raise AttributeError(name)
    params = list(inspect.signature(getattr(mavlink.MAVLink, name)).parameters.values())[1:]  # its defaults
    ns: dict[str, Any] = {"_P": Packed, "_pack": cls.unpacker.pack, "_strip": _strip}
    args = []
    for i, prm in enumerate(params):
        if prm.default is inspect.Parameter.empty:
            args.append(prm.name)
        else:
            ns[f"_d{i}"] = prm.default
            args.append(f"{prm.name}=_d{i}")
    types = dict(zip(cls.fieldnames, cls.fieldtypes, strict=True))
    wire_args = []
    for field, n in zip(cls.ordered_fieldnames, cls.array_lengths, strict=True):
        if n and types[field] != "char":
            wire_args += [f"{field}[{k}]" for k in range(n)]
        else:
            wire_args.append(field)
    src = (f"def {name}({', '.join(args)}):\n"
           f"    return _P({cls.id}, {cls.crc_extra}, _strip(_pack({', '.join(wire_args)})))\n")
    exec(src, ns)  # noqa: S102 - generated from pymavlink's own message definitions, as pymavlink is
    return ns[name]


class _Encoder:
    """pymavlink's `<message>_encode` methods, returning Packed messages (made on first use)."""

    def __getattr__(self, name: str) -> Any:
        fn = _encoder(name)
        setattr(self, name, fn)
        return fn


ENCODER = _Encoder()
