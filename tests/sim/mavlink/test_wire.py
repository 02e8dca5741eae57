"""The vehicle's own MAVLink 2 framing (sim/mavlink/wire.py) gives pymavlink's bytes, and the
vehicle numbers its packets as MAVLink says (it sent sequence 0 on every packet before)."""

from __future__ import annotations

import math

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
