"""The vehicle's receiver under fuzzing (bounded for CI; benchmarks/bench_fuzz.py runs a
million): random bytes, absurd values in well-formed frames of every message it handles, and
bit-flipped frames. Nothing raises in a handler, the vehicle keeps answering, and what one
sender can grow (peers, frame queue, text history) stays bounded."""

from __future__ import annotations

import time

from plain_gcs import Gcs, M

from sim.mavlink.camera_component import MAX_PENDING_FRAMES
from sim.mavlink.fuzz import send_fuzz
from sim.mavlink.streams import STATUSTEXT_KEEP
from sim.mavlink.udp import MAX_PEERS


def test_fuzzed_datagrams_leave_the_vehicle_answering(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", camera=True)  # the camera component on the same links is fuzzed too
    port = sitl.cfg.gcs_ports[0]
    for seed in range(4):  # 4 x 1500, from 300 one-shot senders: paced so the socket keeps up
        send_fuzz(port, 1500, seed, sitl.cfg.sysid, per_sender=20)
        time.sleep(0.3)
    v = sitl.vehicle
    # let the vehicle drain its socket before counting (on a loaded box it lags the sender)
    end, last = time.monotonic() + 10.0, -1
    while time.monotonic() < end and (now := v.links[1].stats.received + v.links[1].stats.bad_data) != last:
        last = now
        time.sleep(0.5)
    assert not v.counters.handler_errors, v.counters.handler_errors[:5]
    assert not sitl.errors, sitl.errors[:1]
    assert len(v.links[1].peers) <= MAX_PEERS + 1, "one-shot senders do not all become telemetry peers"
    assert len(v.counters.statustext) <= STATUSTEXT_KEEP and sitl.camera._pending <= MAX_PENDING_FRAMES
    assert v.links[1].stats.bad_data > 100, "the random and bit-flipped ones were dropped as malformed"
    # ~6000 datagrams, 60 % well-formed over every handled message type: COMMAND_* are ~100 of
    # them; UDP may drop some under load, so ask for half
    assert v.counters.commands > 50, "the well-formed ones reached the command handlers"
    g = Gcs(sitl.cfg.gcs_ports[1], sysid=sitl.cfg.sysid)
    try:
        assert g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_HEARTBEAT, 1e6).result == M.MAV_RESULT_ACCEPTED
        assert g.recv("HEARTBEAT", 3) is not None, "still heartbeating"
    finally:
        g.close()
