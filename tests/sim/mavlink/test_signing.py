"""MAVLink 2 signing as an attacker and a late client see it: a signed command replayed onto
the vehicle's other link, a forged packet with the largest timestamp, a signed one far in the
future, a client joining a vehicle that has run for minutes, and unsigned writes."""

from __future__ import annotations

import socket
import time

from plain_gcs import Gcs, M
from pymavlink.dialects.v20 import common as v20

KEY = bytes(range(32))


def _signed(sysid: int, ts_offset_s: float = 0.0, link_id: int = 3) -> v20.MAVLink:
    from sim.mavlink.udp import signing_timestamp

    mav = v20.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.signing.secret_key, mav.signing.sign_outgoing, mav.signing.link_id = KEY, True, link_id
    mav.signing.timestamp = signing_timestamp() + int(ts_offset_s * 100_000)
    return mav


def _arm(mav: v20.MAVLink, sysid: int, arm: float) -> bytes:
    return mav.command_long_encode(sysid, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, arm, 0, 0, 0, 0, 0, 0).pack(mav)


def _until(pred, timeout: float = 3.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not pred():
        time.sleep(0.02)
    return pred()


def test_a_signed_command_replayed_onto_the_other_link_is_refused(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", signing_key=KEY)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        _until(lambda: sitl.vehicle.fix is not None, 10)
        mav = _signed(sitl.cfg.sysid)
        arm = _arm(mav, sitl.cfg.sysid, 1)
        sock.sendto(arm, ("127.0.0.1", sitl.cfg.api_ports[0]))
        assert _until(lambda: sitl.model.state.armed), "the signed ARM is obeyed"
        sock.sendto(_arm(mav, sitl.cfg.sysid, 0), ("127.0.0.1", sitl.cfg.api_ports[0]))
        assert _until(lambda: not sitl.model.state.armed)
        sock.sendto(arm, ("127.0.0.1", sitl.cfg.gcs_ports[0]))  # the recorded ARM, on the other link
        time.sleep(0.5)
        assert not sitl.model.state.armed and sitl.vehicle.signing_guard.refused["replay"] >= 1
    finally:
        sock.close()


def test_forged_and_future_timestamps_lock_nobody_out(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", signing_key=KEY)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        _until(lambda: sitl.vehicle.fix is not None, 10)
        # a forged packet (no key) in the legitimate client's stream, with the largest timestamp
        forger = v20.MAVLink(None, srcSystem=255, srcComponent=190)
        forger.signing.secret_key, forger.signing.sign_outgoing, forger.signing.link_id = bytes(32), True, 3
        forger.signing.timestamp = (1 << 48) - 10
        sock.sendto(_arm(forger, sitl.cfg.sysid, 1), ("127.0.0.1", sitl.cfg.api_ports[0]))
        # a correctly signed packet from a clock ten minutes fast
        sock.sendto(_arm(_signed(sitl.cfg.sysid, 600.0, link_id=4), sitl.cfg.sysid, 1), ("127.0.0.1", sitl.cfg.api_ports[0]))
        time.sleep(0.3)
        assert not sitl.model.state.armed
        refused = sitl.vehicle.signing_guard.refused
        assert refused["signature"] >= 1 and refused["ahead"] >= 1
        # the legitimate client, same stream as the forgery: still obeyed
        sock.sendto(_arm(_signed(sitl.cfg.sysid), sitl.cfg.sysid, 1), ("127.0.0.1", sitl.cfg.api_ports[0]))
        assert _until(lambda: sitl.model.state.armed)
    finally:
        sock.close()


def test_a_client_joining_minutes_later_accepts_the_vehicles_packets(sitl_factory) -> None:
    """pymavlink refuses a new stream more than a minute behind its own clock: a vehicle whose
    signing clock stayed where it started was deaf-mute to any client joining later."""
    sitl = sitl_factory(physics="kinematic", signing_key=KEY)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(0.5)
    sock.bind(("127.0.0.1", sitl.cfg.gcs_ports[1]))  # the ground station's port: the vehicle streams here
    for link in sitl.vehicle.links:  # as if the vehicle had started five minutes ago
        link.mav.signing.timestamp -= 300 * 100_000
    client = _signed(sitl.cfg.sysid)  # a verifying receiver whose clock is now
    client.signing.sign_outgoing = False
    heartbeats = 0
    try:
        end = time.monotonic() + 5
        while heartbeats < 2 and time.monotonic() < end:
            try:
                data = sock.recv(2000)
            except TimeoutError:
                continue
            try:
                msgs = client.parse_buffer(data) or []
            except Exception:  # noqa: BLE001 - a refused signature raises in pymavlink
                msgs = []
            heartbeats += sum(m.get_type() == "HEARTBEAT" for m in msgs)
        assert heartbeats >= 2 and client.signing.goodsig_count >= 2
    finally:
        sock.close()


def test_with_signing_on_nothing_unsigned_changes_anything(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", signing_key=KEY)
    g = Gcs(sitl.cfg.gcs_ports[1], sysid=sitl.cfg.sysid)  # unsigned
    try:
        before = dict((n, sitl.vehicle.params[n]) for n in ("GF_MAX_HOR_DIST", "NAV_DLL_ACT"))
        g.c.mav.param_set_send(g.sysid, 1, b"GF_MAX_HOR_DIST", 10000.0, M.MAV_PARAM_TYPE_REAL32)
        g.c.mav.param_set_send(g.sysid, 1, b"NAV_DLL_ACT", 0.0, M.MAV_PARAM_TYPE_REAL32)
        g.c.mav.mission_count_send(g.sysid, 1, 1, M.MAV_MISSION_TYPE_MISSION)
        g.c.mav.command_long_send(g.sysid, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, M.MAVLINK_MSG_ID_GPS_RAW_INT, -1,
                                  0, 0, 0, 0, 0)
        time.sleep(0.5)
        assert {n: sitl.vehicle.params[n] for n in before} == before
        assert sitl.vehicle.missions.incoming is None and sitl.vehicle.rates[M.MAVLINK_MSG_ID_GPS_RAW_INT] > 0
        assert sitl.vehicle.links[1].stats.rejected_unsigned >= 4
    finally:
        g.close()


def test_a_taken_port_fails_and_bind_is_checked(sitl_factory) -> None:
    import pytest

    from sim.mavlink import SitlConfig
    from sim.mavlink.udp import UdpLink

    sitl = sitl_factory(physics="kinematic")
    with pytest.raises(OSError, match="cannot bind UDP"):
        UdpLink(sitl.cfg.api_ports[0], 9)
    with pytest.raises(ValueError, match="bind"):
        SitlConfig(physics="kinematic", bind="localhost:1")
    link = UdpLink(0, 9, bind="127.0.0.1")
    try:
        assert link.sock.getsockname()[0] == "127.0.0.1"
    finally:
        link.close()
