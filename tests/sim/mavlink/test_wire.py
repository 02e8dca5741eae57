"""The vehicle's own MAVLink 2 framing (sim/mavlink/wire.py) gives pymavlink's bytes, and the
vehicle numbers its packets as MAVLink says (it sent sequence 0 on every packet before)."""

from __future__ import annotations

import math
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from sim.mavlink import wire
from sim.mavlink.telemetry import BUILDERS

M = mavlink


def _messages(sitl) -> list:
    v = sitl.vehicle
    snap = v.snapshot()
    msgs = [b(v.mav, snap) for b in BUILDERS.values()]
    msgs += [v.mav.statustext_encode(M.MAV_SEVERITY_INFO, b"x" * 50, 7, 2),
             v.mav.command_ack_encode(M.MAV_CMD_NAV_TAKEOFF, M.MAV_RESULT_ACCEPTED, 0, 0, 0, 0),
             v.mav.encapsulated_data_encode(3, bytes(range(253))),
             v.mav.param_value_encode(b"COM_OF_LOSS_T", math.nan, M.MAV_PARAM_TYPE_REAL32, 90, 3),
             v.mav.mission_ack_encode(0, 0, 0, 0)]  # all-zero payload: one byte stays
    return [m for m in msgs if m is not None]


def test_frames_are_pymavlinks_bytes(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    ref = mavlink.MAVLink(None, srcSystem=sitl.cfg.sysid, srcComponent=1)
    msgs = _messages(sitl)
    assert len(msgs) >= 14
    for seq, msg in zip([0, 1, 77, 255] * 10, msgs, strict=False):
        ref.seq = seq
        want = msg.pack(ref)
        got = wire.frame(msg, wire.payload(msg), seq, sitl.cfg.sysid, 1)
        assert got == want, msg.get_type()
        assert ref.decode(bytearray(got)).get_type() == msg.get_type()


def test_the_vehicle_numbers_its_packets(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{sitl.cfg.gcs_ports[1]}", source_system=255)
    try:
        seqs = []
        while len(seqs) < 40:
            m = c.recv_match(blocking=True, timeout=5)
            assert m is not None
            if m.get_srcSystem() == sitl.cfg.sysid:
                seqs.append(m.get_seq())
        steps = {(b - a) % 256 for a, b in zip(seqs, seqs[1:], strict=False)}
        assert steps == {1}, seqs  # loopback loses nothing: every packet is the next number
    finally:
        c.close()


def test_the_encoder_packs_pymavlinks_bytes_without_message_objects(sitl_factory) -> None:
    """wire.ENCODER (what the vehicle builds its telemetry with) against pymavlink's messages:
    every telemetry builder, char and uint8 arrays, extension defaults, NaN, an all-zero payload."""
    sitl = sitl_factory(physics="kinematic")
    v, ref = sitl.vehicle, mavlink.MAVLink(None, srcSystem=sitl.cfg.sysid, srcComponent=1)
    assert v.enc is wire.ENCODER, "an unsigned vehicle builds its telemetry with the encoder"
    snaps = [v.snapshot()]
    assert v.arm() and v.takeoff(v.home.alt_m + 3.0) == M.MAV_RESULT_ACCEPTED
    t0, wall0 = sitl.t, time.monotonic()
    while sitl.t < t0 + 1.0 and time.monotonic() < wall0 + 20:  # climbing: non-zero everything
        time.sleep(0.05)
    snaps.append(v.snapshot())
    pairs = [(b(wire.ENCODER, x), b(v.mav, x)) for x in snaps for b in BUILDERS.values()]
    calls = [("statustext_encode", (M.MAV_SEVERITY_INFO, b"x" * 50, 7, 2)),
             ("statustext_encode", (M.MAV_SEVERITY_INFO, b"short")),
             ("encapsulated_data_encode", (3, bytes(range(253)))),
             ("param_value_encode", (b"COM_OF_LOSS_T", math.nan, M.MAV_PARAM_TYPE_REAL32, 90, 3)),
             ("mission_ack_encode", (0, 0, 0, 0)),
             ("mission_current_encode", (2, 5, M.MISSION_STATE_ACTIVE))]
    pairs += [(getattr(wire.ENCODER, n)(*a), getattr(v.mav, n)(*a)) for n, a in calls]
    pairs = [(p, m) for p, m in pairs if m is not None]
    assert len(pairs) >= 26
    for seq, (p, m) in zip([0, 1, 77, 255] * 20, pairs, strict=False):
        ref.seq = seq
        assert wire.frame_packed(p, seq, sitl.cfg.sysid, 1) == m.pack(ref), m.get_type()


def test_frame_all_numbers_and_frames_as_frame_packed() -> None:
    enc = wire.ENCODER
    packets = [enc.heartbeat_encode(2, 12, 81, 65536, 3), enc.mission_ack_encode(0, 0, 0, 0),
               enc.local_position_ned_encode(5, 1.0, 2.0, 3.0, 0.1, 0.2, 0.3)] * 3
    got = wire.frame_all(packets, 250, 7, 1)
    assert got == [wire.frame_packed(p, (250 + k) & 0xFF, 7, 1) for k, p in enumerate(packets)]
