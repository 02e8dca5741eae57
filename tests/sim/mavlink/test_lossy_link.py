"""The link under a bad radio: the seeded fault proxy itself, mission upload through 20 % loss,
the vehicle's answers to a resent last item and to a station that goes quiet, and camera frames
that arrive in pieces, out of order and twice."""

from __future__ import annotations

import math
import random
import socket
import threading
import time

import numpy as np
import pytest
from pymavlink import mavutil
from udp_ports import free_udp_port

from autopilot_bridge.camera import FrameAssembler
from missions.lossy import upload_like_qgc
from sim.mavlink.faultproxy import FaultProxy, LinkFaults
from sim.mavlink.images import frame_messages

M = mavutil.mavlink


def _through_proxy(faults: LinkFaults, seed: int, n: int = 2000) -> tuple[list[bytes], FaultProxy]:
    vport, cport = free_udp_port(), free_udp_port()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", cport))
    client.settimeout(0.3)
    vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle.bind(("127.0.0.1", vport))
    got: list[bytes] = []

    def read() -> None:  # as they come: a socket buffer holds only a few hundred datagrams
        client.settimeout(2.0)
        try:
            while True:
                got.append(client.recv(100))
        except TimeoutError:
            pass

    with FaultProxy(vport, cport, faults, seed=seed) as proxy:
        reader = threading.Thread(target=read)
        reader.start()
        for i in range(n):
            vehicle.sendto(i.to_bytes(4, "big") * 4, ("127.0.0.1", proxy.vehicle_side_port))
            while proxy.down.counts.forwarded < i - 20:  # stay within the socket buffers
                time.sleep(0.001)
        end = time.monotonic() + 10
        while proxy.down.counts.forwarded < n and time.monotonic() < end:  # all in before the proxy stops
            time.sleep(0.01)
        reader.join()
    client.close()
    vehicle.close()
    return got, proxy


def test_fault_proxy_injects_what_it_says_and_replays_from_its_seed() -> None:
    faults = LinkFaults(loss=0.2, duplicate=0.05, reorder=0.05, corrupt=0.02, reorder_ms=5)
    got, proxy = _through_proxy(faults, seed=7)
    c = proxy.down.counts
    assert c.forwarded == 2000
    assert 0.16 < c.lost / 2000 < 0.24 and 0.03 < c.duplicated / 2000 < 0.07 and c.reordered > 40 and c.corrupted > 15
    assert len(got) == 2000 - c.lost + c.duplicated
    seq = [int.from_bytes(g[:4], "big") for g in got if g[:4] * 4 == g]
    assert any(b < a for a, b in zip(seq, seq[1:], strict=False)), "some datagrams overtake others"
    again, proxy2 = _through_proxy(faults, seed=7)
    assert proxy2.down.counts == c, "the same seed injects the same faults"
    with pytest.raises(ValueError, match="loss"):
        LinkFaults(loss=1.5)
    with pytest.raises(ValueError, match="delay"):
        LinkFaults(delay_ms=(5.0, 1.0))


def test_frame_assembler_takes_chunks_out_of_order_twice_and_out_of_range() -> None:
    mav = M.MAVLink(None, srcSystem=1, srcComponent=1)
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (50, 50, 3), dtype=np.uint8)
    msgs = frame_messages(mav, frame)
    hs, chunks = msgs[0], msgs[1:]
    assert len(chunks) > 10
    asm = FrameAssembler()
    asm.feed(hs)
    stray = mav.encapsulated_data_encode(999, b"\0" * 253)  # a chunk no frame announced
    shuffled = chunks + chunks[:3]
    random.Random(1).shuffle(shuffled)
    out = None
    for m in [stray, *shuffled]:
        out = asm.feed(m) if out is None else out
    assert out is not None and np.array_equal(out, frame)
    # a lossy radio: each transmission of the same picture misses chunks; the assembler fills
    # them in from the next one
    asm, out = FrameAssembler(), None
    for k in range(3):
        asm.feed(hs)
        for i, m in enumerate(chunks):
            if i % 3 != k:
                out = out if out is not None else asm.feed(m)
    assert out is not None and np.array_equal(out, frame)


def _item(sysid: int, seq: int, lat: float, lon: float, alt: float, mav):
    cmd = M.MAV_CMD_NAV_TAKEOFF if seq == 0 else M.MAV_CMD_NAV_WAYPOINT
    return mav.mission_item_int_encode(sysid, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, cmd, 0, 1, 0, 0.5, 0, math.nan,
                                       int(lat * 1e7), int(lon * 1e7), alt, M.MAV_MISSION_TYPE_MISSION)


def _mission(c, home, sysid: int, n: int = 8):
    d = 1 / 111_200.0
    lat0, lon0 = home.latitude * 1e-7, home.longitude * 1e-7
    return [_item(sysid, 0, lat0, lon0, 3.5, c.mav)] + [_item(sysid, i, lat0 + 2 * i * d, lon0, 3.5, c.mav) for i in range(1, n)]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_mission_upload_through_20_percent_loss(lossy_sitl, seed: int) -> None:
    faults = LinkFaults(loss=0.2, duplicate=0.05, reorder=0.05, reorder_ms=20)
    sitl, proxy, port = lossy_sitl(faults, seed=seed, physics="kinematic", gcs_link=False)
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255, source_component=190)
    try:
        home = c.recv_match(type="HOME_POSITION", blocking=True, timeout=10)
        assert home is not None
        items = _mission(c, home, sitl.cfg.sysid)
        assert upload_like_qgc(c, sitl.cfg.sysid, items) == M.MAV_MISSION_ACCEPTED
        assert [it.seq for it in sitl.vehicle.mission.items] == list(range(len(items)))
        assert proxy.up.counts.lost + proxy.down.counts.lost > 0
    finally:
        c.close()


def test_a_resent_last_item_is_acked_again(sitl_factory) -> None:
    """The station's copy of the last item crossed our ACK, or the ACK was lost: the vehicle must
    say ACCEPTED again (before, it ignored the item and the station timed out)."""
    sitl = sitl_factory(physics="kinematic")
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{sitl.cfg.gcs_ports[1]}", source_system=255, source_component=190)
    try:
        home = c.recv_match(type="HOME_POSITION", blocking=True, timeout=10)
        items = _mission(c, home, sitl.cfg.sysid, 3)
        assert upload_like_qgc(c, sitl.cfg.sysid, items) == M.MAV_MISSION_ACCEPTED
        c.mav.send(items[-1])
        ack = c.recv_match(type="MISSION_ACK", blocking=True, timeout=3)
        assert ack is not None and ack.type == M.MAV_MISSION_ACCEPTED
    finally:
        c.close()


def test_a_vehicle_that_gives_up_an_upload_says_so(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    sitl.vehicle.missions.RETRY_S = 0.1  # the give-up takes 11 re-requests: keep the test short
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{sitl.cfg.gcs_ports[1]}", source_system=255, source_component=190)
    try:
        assert c.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
        c.mav.mission_count_send(sitl.cfg.sysid, 1, 3, M.MAV_MISSION_TYPE_MISSION)  # ... and then silence
        ack = c.recv_match(type="MISSION_ACK", blocking=True, timeout=8)
        assert ack is not None and ack.type == M.MAV_MISSION_OPERATION_CANCELLED
        assert sitl.vehicle.missions.incoming is None
    finally:
        c.close()


def test_non_finite_mission_items_get_an_error_ack(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{sitl.cfg.gcs_ports[1]}", source_system=255, source_component=190)
    try:
        assert c.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
        for bad, want in (((math.nan, 8.5, 3.0), M.MAV_MISSION_INVALID_PARAM5_X),
                          ((47.3, math.inf, 3.0), M.MAV_MISSION_INVALID_PARAM6_Y),
                          ((47.3, 8.5, math.nan), M.MAV_MISSION_INVALID_PARAM7)):
            c.mav.mission_count_send(sitl.cfg.sysid, 1, 1, M.MAV_MISSION_TYPE_MISSION)
            assert c.recv_match(type="MISSION_REQUEST_INT", blocking=True, timeout=3) is not None
            c.mav.mission_item_send(sitl.cfg.sysid, 1, 0, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_CMD_NAV_WAYPOINT, 0, 1,
                                    0, 0, 0, 0, *bad, M.MAV_MISSION_TYPE_MISSION)
            ack = c.recv_match(type="MISSION_ACK", blocking=True, timeout=3)
            assert ack is not None and ack.type == want
        assert not sitl.vehicle.counters.handler_errors
    finally:
        c.close()


def test_long_statustext_goes_out_in_chunks(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{sitl.cfg.gcs_ports[1]}", source_system=255, source_component=190)
    try:
        assert c.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
        text = "Geofence: " + "x" * 90 + " the end"  # 108 characters: three chunks
        sitl.vehicle.statustext(text)
        parts = {}
        end = time.monotonic() + 5
        while len(parts) < 3 and time.monotonic() < end:
            m = c.recv_match(type="STATUSTEXT", blocking=True, timeout=1)
            if m is not None and m.id != 0:
                parts[m.chunk_seq] = (m.id, m.text)
        assert sorted(parts) == [0, 1, 2] and len({i for i, _ in parts.values()}) == 1
        assert "".join(parts[k][1] for k in range(3)) == text
    finally:
        c.close()


def test_a_timed_capture_asked_again_later_is_the_same_picture(lossy_sitl) -> None:
    """A lossy link needs several asks for one frame, each ~2.5 s apart (command resends plus
    the wait): the camera must resend the picture of the asked time however late the ask
    comes, so the receiver can fill its gaps. It used to render a new picture after 3 wall
    seconds, which threw the gathered chunks away (one frame took 16 s, and a 64-move search
    through 20 % loss failed)."""
    from autopilot_bridge.camera import FrameRequester
    from autopilot_bridge.link.connection import VehicleLink
    from sim.mavlink.camera_component import FRAME_REUSE_S

    faults = LinkFaults(duplicate=0.05, reorder=0.05, delay_ms=(0.0, 2.0), reorder_ms=10)
    sitl, proxy, port = lossy_sitl(faults, seed=5, physics="kinematic", camera=True, gcs_link=False)
    with VehicleLink(f"udpin:127.0.0.1:{port}") as link:
        link.wait_heartbeat()
        at = sitl.t + 0.5
        frame, t1 = FrameRequester(link).capture(at, timeout=3.0, tries=3)
        assert frame is not None and t1 is not None and t1 >= at - 1e-6  # the stamp is written to 1e-6 s
        time.sleep(FRAME_REUSE_S + 0.5)
        again, t2 = FrameRequester(link).capture(at, timeout=3.0, tries=3)  # a fresh assembler: the wire's answer
        assert again is not None and t2 == t1, f"a new picture ({t2}) instead of the one of {t1}"
        assert np.array_equal(again, frame)
        assert sitl.t > t1 + FRAME_REUSE_S, "simulated time ran on meanwhile"
    assert proxy.down.counts.duplicated + proxy.down.counts.reordered > 0


def test_a_land_resent_after_touchdown_is_accepted(sitl_factory) -> None:
    """LAND's ACK lost, the companion resends it; meanwhile the vehicle has landed and
    disarmed. The resent LAND must not be refused (it was: TEMPORARILY_REJECTED, and a
    64-move search through 20 % loss that had flown every move ended as a failure)."""
    from autopilot_bridge.link.connection import VehicleLink

    sitl = sitl_factory(physics="kinematic", speedup=10.0, gcs_link=False)
    with VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}") as link:
        link.wait_heartbeat()
        link.wait_for(lambda: link.telemetry.gps.get("fix_type", 0) >= 3 and bool(link.telemetry.home), 10, "a fix")
        link.arm()
        link.takeoff(link.telemetry.home["alt"] + 2.0)
        link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -1.5, 20, "take-off")
        link.land()
        link.wait_for(lambda: not link.telemetry.armed, 20, "landing and disarm")
        link.land()  # the resend: accepted, nothing to do
        assert not sitl.model.state.armed and sitl.model.state.landed
