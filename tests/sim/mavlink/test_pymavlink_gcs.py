"""The same flight with a plain pymavlink ground station, plus the protocol's edges."""

import json
import logging
import math
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from plain_gcs import Gcs, M
from pymavlink import mavutil

from autopilot_bridge.camera import FrameAssembler
from sim.mavlink import Geofence
from sim.mavlink.sitl import TICK_S


def _upload(g: Gcs, items) -> int:
    g.c.mav.mission_count_send(g.sysid, 1, len(items), M.MAV_MISSION_TYPE_MISSION)
    while True:
        m = g.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], 5)
        assert m is not None, "vehicle stopped asking for items"
        if m.get_type() == "MISSION_ACK":
            return m.type
        g.c.mav.send(items[m.seq])


def _item(g: Gcs, seq: int, cmd: int, lat: float, lon: float, alt: float):
    return g.c.mav.mission_item_int_encode(g.sysid, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, cmd, 0, 1, 0, 0.5, 0, math.nan,
                                           int(lat * 1e7), int(lon * 1e7), alt, M.MAV_MISSION_TYPE_MISSION)


def _take_off(g: Gcs) -> None:
    """Arm, take off (to MIS_TAKEOFF_ALT) and wait until the vehicle says it is in the air."""
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan).result == M.MAV_RESULT_ACCEPTED
    assert g.recv("EXTENDED_SYS_STATE", 10, lambda m: m.landed_state == M.MAV_LANDED_STATE_IN_AIR)


def test_pymavlink_flight_and_mission_download(sitl_factory) -> None:
    sitl = sitl_factory(physics="pybullet", camera=False)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        assert g.recv("GPS_RAW_INT", 5, lambda m: m.fix_type == 3) is not None
        home = g.recv("HOME_POSITION", 5)
        lat0, lon0 = home.latitude * 1e-7, home.longitude * 1e-7
        d = 1 / 111_200.0
        items = [_item(g, 0, M.MAV_CMD_NAV_TAKEOFF, lat0, lon0, 3.5)] + [
            _item(g, i + 1, M.MAV_CMD_NAV_WAYPOINT, lat0 + dn * d, lon0 + de * d / math.cos(math.radians(lat0)), 3.5)
            for i, (dn, de) in enumerate([(6, 0), (6, 6), (0, 6), (0, 0)])
        ] + [_item(g, 5, M.MAV_CMD_NAV_LAND, lat0, lon0, 0)]
        assert _upload(g, items) == M.MAV_MISSION_ACCEPTED
        # download equals upload
        g.c.mav.mission_request_list_send(g.sysid, 1, M.MAV_MISSION_TYPE_MISSION)
        count = g.recv("MISSION_COUNT", 5).count
        got = []
        for i in range(count):
            g.c.mav.mission_request_int_send(g.sysid, 1, i, M.MAV_MISSION_TYPE_MISSION)
            got.append(g.recv("MISSION_ITEM_INT", 5, lambda m, i=i: m.seq == i))
        g.c.mav.mission_ack_send(g.sysid, 1, M.MAV_MISSION_ACCEPTED, M.MAV_MISSION_TYPE_MISSION)
        assert [(m.command, m.x, m.y, m.z) for m in got] == [(m.command, m.x, m.y, m.z) for m in items]

        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert g.command(M.MAV_CMD_MISSION_START, 0, 0).result == M.MAV_RESULT_ACCEPTED
        reached = set()
        end = time.monotonic() + 60
        while time.monotonic() < end and len(reached) < 5:
            m = g.recv("MISSION_ITEM_REACHED", 1)
            if m is not None:
                reached.add(m.seq)
        assert reached >= {0, 1, 2, 3, 4}
        hb_disarmed = g.recv("HEARTBEAT", 30, lambda h: not h.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
        assert hb_disarmed is not None, "lands and disarms at the end of the mission"
        # telemetry agrees with physics
        gp = g.recv("GLOBAL_POSITION_INT", 3)
        ned = sitl.home.geodetic_to_ned(gp.lat * 1e-7, gp.lon * 1e-7, gp.alt * 1e-3)
        assert np.linalg.norm(ned[:2] - sitl.model.state.position_ned[:2]) < 4.0
        ess = g.recv("EXTENDED_SYS_STATE", 3)
        assert ess.landed_state == M.MAV_LANDED_STATE_ON_GROUND
    finally:
        g.close()


def test_command_acks_are_honest(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan).result == M.MAV_RESULT_TEMPORARILY_REJECTED
        assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 99, 0).result == M.MAV_RESULT_UNSUPPORTED
        assert g.command(M.MAV_CMD_MISSION_START).result == M.MAV_RESULT_DENIED  # no mission
        assert g.command(M.MAV_CMD_DO_FLIGHTTERMINATION, 1).result == M.MAV_RESULT_UNSUPPORTED
        custom = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        assert g.command(M.MAV_CMD_DO_SET_MODE, custom, 3, 0).result == M.MAV_RESULT_TEMPORARILY_REJECTED, "no sticks"
        assert g.command(M.MAV_CMD_DO_SET_MODE, custom, 2, 0).result == M.MAV_RESULT_DENIED, "ALTCTL not flown"
        assert g.command(M.MAV_CMD_DO_SET_MODE, custom, 4, 2).result == M.MAV_RESULT_TEMPORARILY_REJECTED, "takeoff, disarmed"
        assert g.command(M.MAV_CMD_DO_SET_MODE, custom, 4, 5).result == M.MAV_RESULT_TEMPORARILY_REJECTED, "RTL, on ground"
        assert g.command(M.MAV_CMD_DO_SET_MODE, custom, 6, 0).result == M.MAV_RESULT_TEMPORARILY_REJECTED, "no setpoints"
        handshake = g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE)
        assert handshake.result == M.MAV_RESULT_DENIED, "a flight controller serves no frames (as real PX4)"
        assert g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION).result == M.MAV_RESULT_ACCEPTED
        av = g.recv("AUTOPILOT_VERSION", 3)
        assert av.capabilities & M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
        assert not av.capabilities & M.MAV_PROTOCOL_CAPABILITY_FTP, "claims only what it does"
        g.c.mav.timesync_send(0, 123_456_789)
        ts = g.recv("TIMESYNC", 3, lambda m: m.ts1 == 123_456_789)
        assert ts is not None and ts.tc1 > 0, "TIMESYNC requests are answered with the vehicle's clock"
        assert g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, 20_000).result == M.MAV_RESULT_ACCEPTED
        t0 = time.monotonic()
        n = sum(g.recv("ATTITUDE", 1) is not None for _ in range(20))
        assert n == 20 and time.monotonic() - t0 < 2.0
        _take_off(g)
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_DENIED, "no disarm in the air"
        # COMMAND_INT: reposition 5 m north at 4 m relative altitude, lat/lon as integers
        home = g.recv("HOME_POSITION", 5)
        g.c.mav.command_int_send(g.sysid, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_CMD_DO_REPOSITION, 0, 0,
                                 -1, 0, 0, math.nan, home.latitude + int(5 / 111_200.0 * 1e7), home.longitude, 4.0)
        assert g.recv("COMMAND_ACK", 3, lambda a: a.command == M.MAV_CMD_DO_REPOSITION).result == M.MAV_RESULT_ACCEPTED
        end = time.monotonic() + 5
        while time.monotonic() < end and np.linalg.norm(sitl.vehicle.estimate() - [5.0, 0.0, -4.0]) > 0.3:
            time.sleep(0.05)
        assert np.linalg.norm(sitl.vehicle.estimate() - [5.0, 0.0, -4.0]) < 0.3
    finally:
        g.close()


def test_geofence_rejects_out_of_bounds_targets(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        home = g.recv("HOME_POSITION", 5)
        far_lat = home.latitude * 1e-7 + 500 / 111_200.0  # 500 m north: beyond GF_MAX_HOR_DIST = 100
        items = [_item(g, 0, M.MAV_CMD_NAV_WAYPOINT, far_lat, home.longitude * 1e-7, 3.5)]
        assert _upload(g, items) == M.MAV_MISSION_DENIED
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan).result == M.MAV_RESULT_ACCEPTED
        g.recv("EXTENDED_SYS_STATE", 10, lambda m: m.landed_state == M.MAV_LANDED_STATE_IN_AIR)
        ack = g.command(M.MAV_CMD_DO_REPOSITION, -1, 0, 0, math.nan, far_lat, home.longitude * 1e-7, home.altitude * 1e-3 + 3.5)
        assert ack.result == M.MAV_RESULT_DENIED
        g.recv("HEARTBEAT", 1)
        assert any("Geofence" in t for t in g.texts), g.texts
        time.sleep(0.5)
        assert np.hypot(*sitl.model.state.position_ned[:2]) < 5.0, "it never flew there"
        assert sitl.vehicle.counters.fence_rejections >= 2
    finally:
        g.close()


def test_parameters_list_read_set_and_bad_values(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        g.c.mav.param_request_list_send(g.sysid, 1)
        names = set()
        first = g.recv("PARAM_VALUE", 3)
        names.add(first.param_id)
        while len(names) < first.param_count:
            m = g.recv("PARAM_VALUE", 2)
            assert m is not None
            names.add(m.param_id)
        assert {"MIS_TAKEOFF_ALT", "NAV_ACC_RAD", "GF_MAX_HOR_DIST"} <= names
        g.c.mav.param_set_send(g.sysid, 1, b"NAV_ACC_RAD", 0.8, M.MAV_PARAM_TYPE_REAL32)
        assert g.recv("PARAM_VALUE", 3, lambda m: m.param_id == "NAV_ACC_RAD").param_value == pytest.approx(0.8)
        g.c.mav.param_set_send(g.sysid, 1, b"NAV_ACC_RAD", -5.0, M.MAV_PARAM_TYPE_REAL32)
        echo = g.recv("PARAM_VALUE", 3, lambda m: m.param_id == "NAV_ACC_RAD")
        assert echo.param_value == pytest.approx(0.8), "a bad value is refused and the old one kept"
        g.c.mav.param_request_read_send(g.sysid, 1, b"MIS_TAKEOFF_ALT", -1)
        assert g.recv("PARAM_VALUE", 3, lambda m: m.param_id == "MIS_TAKEOFF_ALT").param_value == pytest.approx(3.5)
    finally:
        g.close()


def test_malformed_bytes_are_counted_and_survived(sitl_factory, caplog) -> None:
    caplog.set_level(logging.WARNING, logger="sim.mavlink.udp")
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        good = g.c.mav.command_long_encode(g.sysid, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(g.c.mav)
        bad_crc = bytearray(good)
        bad_crc[-1] ^= 0xFF
        for junk in (b"\x00" * 40, bytes(range(256)), bytes(bad_crc), good[: len(good) // 2], b"\xfd\xff"):
            sock.sendto(junk, ("127.0.0.1", sitl.cfg.gcs_ports[0]))
        time.sleep(0.3)
        assert sitl.vehicle.links[1].stats.bad_data >= 3
        assert any("dropped a datagram" in r.getMessage() for r in caplog.records)
        assert g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION).result == M.MAV_RESULT_ACCEPTED
        assert not sitl.errors
    finally:
        g.close()


def test_signing_rejects_unsigned_commands(sitl_factory) -> None:
    key = bytes(range(32))
    sitl = sitl_factory(physics="kinematic", signing_key=key)
    unsigned = Gcs(sitl.cfg.gcs_ports[1])  # heartbeats are readable; commands must be signed
    try:
        assert unsigned.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout=1.5) is None
        assert not sitl.model.state.armed
        assert sitl.vehicle.links[1].stats.rejected_unsigned >= 1
    finally:
        unsigned.close()
    signed = Gcs(sitl.cfg.gcs_ports[1], signing_key=key)  # verifies the vehicle's signed heartbeat
    try:
        assert signed.c.recv_match(type="HEARTBEAT", blocking=True, timeout=3).get_signed()
        assert signed.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert sitl.model.state.armed
        signed.c.mav.param_request_read_send(signed.sysid, 1, b"UAVS_SIGNING", -1)
        assert signed.recv("PARAM_VALUE", 3, lambda m: m.param_id == "UAVS_SIGNING").param_value == 1.0
        signed.c.mav.param_set_send(signed.sysid, 1, b"UAVS_SIGNING", 0.0, M.MAV_PARAM_TYPE_REAL32)
        echo = signed.recv("PARAM_VALUE", 3, lambda m: m.param_id == "UAVS_SIGNING")
        assert echo.param_value == 1.0, "signing cannot be switched off over the link"
    finally:
        signed.close()
    rejected = sitl.vehicle.links[1].stats.rejected_unsigned
    wrong = Gcs(sitl.cfg.gcs_ports[1], signing_key=bytes(32), sysid=sitl.cfg.sysid)
    try:
        assert wrong.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196, timeout=1.5) is None
        assert sitl.model.state.armed, "a wrongly signed disarm is not executed"
        assert sitl.vehicle.links[1].stats.rejected_unsigned > rejected
    finally:
        wrong.close()


def test_camera_frames_over_image_transmission_and_tlog(sitl_factory, tmp_path) -> None:
    tlog = tmp_path / "flight.tlog"
    sitl = sitl_factory(physics="pybullet", camera=True, tlog=tlog)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        asm = FrameAssembler()
        # the camera component (100) on the vehicle's link serves the frames; the autopilot does not
        ack = g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE,
                        component=M.MAV_COMP_ID_CAMERA)
        assert ack.result == M.MAV_RESULT_ACCEPTED and ack.get_srcComponent() == M.MAV_COMP_ID_CAMERA
        frame = None
        end = time.monotonic() + 5
        while frame is None and time.monotonic() < end:
            m = g.recv(["DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA"], 1)
            if m is not None:
                assert m.get_srcComponent() == M.MAV_COMP_ID_CAMERA
                frame = asm.feed(m)
        assert frame is not None and frame.shape == (50, 50, 3)
        assert 60 < frame[..., 1].mean() < 200, "a rendered field, not a blank"
        # the protocol's own request: the receiver's handshake
        g.c.mav.data_transmission_handshake_send(M.MAVLINK_DATA_STREAM_IMG_PNG, 0, 0, 0, 0, 0, 0)
        hs = g.recv("DATA_TRANSMISSION_HANDSHAKE", 3)
        assert hs is not None and hs.type == M.MAVLINK_DATA_STREAM_IMG_PNG and hs.width == 50 and hs.packets > 0
    finally:
        g.close()
    sitl.stop()
    log = mavutil.mavlink_connection(str(tlog))
    kinds = set()
    while (m := log.recv_match()) is not None:
        kinds.add(m.get_type())
    assert {"HEARTBEAT", "GPS_RAW_INT", "COMMAND_LONG", "COMMAND_ACK", "ENCAPSULATED_DATA"} <= kinds
    dump = subprocess.run([sys.executable, str(Path(sys.executable).with_name("mavlogdump.py")), "--types", "COMMAND_ACK",
                           str(tlog)], capture_output=True, text=True, timeout=60)
    assert dump.returncode == 0 and "COMMAND_ACK" in dump.stdout, dump.stderr[-500:]
    meta = json.loads(tlog.with_name("flight.tlog.json").read_text())
    assert meta["seed"] == sitl.cfg.seed and meta["git_revision"] and meta["config"]["physics"] == "pybullet"
    assert meta["config"]["signing"] is False and "signing_key" not in meta["config"]


def test_mission_clear_set_current_and_global_offboard_setpoints(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        home = g.recv("HOME_POSITION", 5)
        lat0, lon0 = home.latitude * 1e-7, home.longitude * 1e-7
        items = [_item(g, i, M.MAV_CMD_NAV_WAYPOINT, lat0 + i * 1e-5, lon0, 3.5) for i in range(3)]
        assert _upload(g, items) == M.MAV_MISSION_ACCEPTED
        g.c.mav.mission_set_current_send(g.sysid, 1, 2)
        assert g.recv("MISSION_CURRENT", 3, lambda m: m.seq == 2) is not None
        g.c.mav.mission_clear_all_send(g.sysid, 1, M.MAV_MISSION_TYPE_MISSION)
        assert g.recv("MISSION_ACK", 3).type == M.MAV_MISSION_ACCEPTED
        g.c.mav.mission_request_list_send(g.sysid, 1, M.MAV_MISSION_TYPE_MISSION)
        assert g.recv("MISSION_COUNT", 3).count == 0
        # OFFBOARD with global setpoints: stream first, then switch, then fly there
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan).result == M.MAV_RESULT_ACCEPTED
        g.recv("EXTENDED_SYS_STATE", 10, lambda m: m.landed_state == M.MAV_LANDED_STATE_IN_AIR)
        goal_lat = lat0 + 6 / 111_200.0
        ignore_vel_acc = 0b0000_1111_1111_1000
        for _ in range(3):
            g.c.mav.set_position_target_global_int_send(0, g.sysid, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, ignore_vel_acc,
                                                        int(goal_lat * 1e7), int(lon0 * 1e7), 4.0, 0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.02)
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0).result == M.MAV_RESULT_ACCEPTED
        end = time.monotonic() + 10
        while time.monotonic() < end and np.linalg.norm(sitl.vehicle.estimate() - [6.0, 0.0, -4.0]) > 0.3:
            g.c.mav.set_position_target_global_int_send(0, g.sysid, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, ignore_vel_acc,
                                                        int(goal_lat * 1e7), int(lon0 * 1e7), 4.0, 0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.05)
        assert np.linalg.norm(sitl.vehicle.estimate() - [6.0, 0.0, -4.0]) < 0.3
    finally:
        g.close()


def test_velocity_setpoints_stop_at_the_geofence(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", geofence=Geofence(max_horizontal_m=12.0, max_altitude_m=10.0))
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        _take_off(g)
        vel_only = 0b0000_1101_1100_0111  # ignore position, acceleration, yaw, yaw rate

        def north(n: int) -> None:
            for _ in range(n):
                g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, vel_only,
                                                           0, 0, 0, 4.0, 0, 0, 0, 0, 0, 0, 0)
                time.sleep(0.05)

        north(3)
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0).result == M.MAV_RESULT_ACCEPTED
        furthest = 0.0
        for _ in range(40):  # ~ 2 s wall, 12 s simulated: far beyond the fence at 4 m/s
            north(1)
            furthest = max(furthest, float(np.hypot(*sitl.model.state.position_ned[:2])))
        assert 5.0 < furthest <= 12.0 + 2.0, furthest  # it flew north, and stopped at the fence (+ GPS bias)
        assert any("Geofence breach" in t for t in g.texts) or g.recv("STATUSTEXT", 2, lambda m: "breach" in m.text)
        hb = g.recv("HEARTBEAT", 3)
        assert (hb.custom_mode >> 16) & 0xFF == 4 and hb.custom_mode >> 24 == 3, "AUTO.LOITER after the breach"
    finally:
        g.close()


def test_two_vehicles_share_the_gcs_port_with_their_own_system_ids(sitl_factory) -> None:
    a = sitl_factory(physics="kinematic", instance=3)
    b = sitl_factory(physics="kinematic", instance=4, gcs_remote_port=a.cfg.gcs_ports[1])
    g = Gcs(a.cfg.gcs_ports[1], sysid=a.cfg.sysid)  # as QGC on 14550 with PX4 instances 3 and 4
    try:
        seen = set()
        end = time.monotonic() + 5
        while len(seen) < 2 and time.monotonic() < end:
            hb = g.recv("HEARTBEAT", 1)
            if hb is not None:
                seen.add(hb.get_srcSystem())
        assert seen == {4, 5}, "PX4 SITL numbering: instance N is system N+1"
        arm_b = g.c.mav.command_long_encode(5, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        for port in (a.cfg.gcs_ports[0], b.cfg.gcs_ports[0]):  # a command for B, delivered to both
            g.c.port.sendto(arm_b.pack(g.c.mav), ("127.0.0.1", port))
        ack = g.recv("COMMAND_ACK", 3)
        assert ack is not None and ack.get_srcSystem() == 5 and ack.result == M.MAV_RESULT_ACCEPTED
        time.sleep(0.2)
        assert b.model.state.armed and not a.model.state.armed, "only the addressed vehicle acts"
    finally:
        g.close()


def test_well_formed_messages_with_absurd_content_are_survived(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        nan, inf = math.nan, math.inf
        mav, sysid = g.c.mav, g.sysid
        for cmd in (M.MAV_CMD_COMPONENT_ARM_DISARM, M.MAV_CMD_DO_SET_MODE, M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_LAND,
                    M.MAV_CMD_MISSION_START, M.MAV_CMD_DO_REPOSITION, M.MAV_CMD_DO_CHANGE_SPEED,
                    M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAV_CMD_REQUEST_MESSAGE):
            for v in (nan, inf, -inf, 1e30, -1e30):
                mav.command_long_send(sysid, 1, cmd, 0, v, v, v, v, v, v, v)
                mav.command_int_send(sysid, 1, 255, cmd, 0, 0, v, v, v, v, 2**31 - 1, -(2**31), v)
        mav.mission_item_int_send(sysid, 1, 7, 0, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0)  # no upload under way
        mav.mission_request_int_send(sysid, 1, 65535)
        mav.mission_set_current_send(sysid, 1, 65535)
        mav.mission_count_send(sysid, 1, 65535, M.MAV_MISSION_TYPE_MISSION)
        mav.mission_count_send(sysid, 1, 0, 255)
        mav.param_set_send(sysid, 1, b"\xff\xfe\x00", nan, M.MAV_PARAM_TYPE_REAL32)
        mav.param_set_send(sysid, 1, b"NAV_ACC_RAD", inf, M.MAV_PARAM_TYPE_REAL32)
        mav.param_request_read_send(sysid, 1, b"", 30000)
        mav.set_position_target_local_ned_send(0, sysid, 1, 1, 0, nan, inf, -inf, nan, nan, nan, 0, 0, 0, nan, nan)
        mav.set_position_target_global_int_send(0, sysid, 1, 6, 0, 2**31 - 1, -(2**31), nan, 0, 0, 0, 0, 0, 0, 0, 0)
        time.sleep(0.5)
        while g.c.recv_match(blocking=False) is not None:  # the answers to all that
            pass
        ack = g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED, "still answering"
        assert sitl.running and not sitl.errors
        assert not sitl.vehicle.counters.handler_errors, sitl.vehicle.counters.handler_errors[:3]
        assert np.all(np.isfinite(sitl.model.state.position_ned)), "nothing absurd reached the airframe"
        assert sitl.vehicle.params["NAV_ACC_RAD"] == pytest.approx(0.4)
        rates = sitl.vehicle.rates
        assert all(math.isfinite(hz) for hz in rates.values()) and rates[M.MAVLINK_MSG_ID_HEARTBEAT] == 1.0
    finally:
        g.close()


def test_return_to_launch_climbs_returns_lands_and_disarms(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", speedup=12.0)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        home = g.recv("HOME_POSITION", 5)
        _take_off(g)
        north = home.latitude * 1e-7 + 8 / 111_200.0
        ack = g.command(M.MAV_CMD_DO_REPOSITION, -1, 0, 0, math.nan, north, home.longitude * 1e-7, home.altitude * 1e-3 + 3.5)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        end = time.monotonic() + 5
        while time.monotonic() < end and sitl.vehicle.estimate()[0] < 7.5:
            time.sleep(0.05)
        assert g.command(M.MAV_CMD_NAV_RETURN_TO_LAUNCH).result == M.MAV_RESULT_ACCEPTED
        highest, end = 0.0, time.monotonic() + 10
        while time.monotonic() < end and sitl.model.state.armed:
            highest = max(highest, -float(sitl.model.state.position_ned[2]))
            time.sleep(0.02)
        assert not sitl.model.state.armed and sitl.model.state.landed, "landed and disarmed"
        assert highest > sitl.vehicle.params["RTL_RETURN_ALT"] - 1.0, "climbed to RTL_RETURN_ALT first"
        assert np.hypot(*sitl.vehicle.estimate()[:2]) < 1.0, "back over home"
    finally:
        g.close()


def test_client_timers_run_on_wall_clock_when_the_simulation_races(sitl_factory) -> None:
    """At speedup 0 simulated time runs hundreds of times faster than the ground station:
    mission re-requests and the offboard-loss timeout must still wait for it."""
    sitl = sitl_factory(physics="kinematic", speedup=0)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        home = g.recv("HOME_POSITION", 5)
        lat0, lon0 = home.latitude * 1e-7, home.longitude * 1e-7
        items = [_item(g, i, M.MAV_CMD_NAV_WAYPOINT, lat0 + i * 1e-5, lon0, 3.5) for i in range(3)]
        g.c.mav.mission_count_send(g.sysid, 1, len(items), M.MAV_MISSION_TYPE_MISSION)
        first = g.recv("MISSION_REQUEST_INT", 3)
        assert first is not None and first.seq == 0
        time.sleep(0.2)  # a slow station: far longer than the retry period in simulated time
        assert _upload_rest(g, items, first) == M.MAV_MISSION_ACCEPTED
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        hold = 0b0000_1101_1111_1000  # position only
        stop = threading.Event()

        def stream() -> None:  # a client's setpoint stream at 5 Hz of wall-clock time
            while not stop.is_set():
                g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, hold, 0, 0, -2.0,
                                                           0, 0, 0, 0, 0, 0, 0, 0)
                time.sleep(0.2)  # many simulated seconds, well within COM_OF_LOSS_T of wall-clock time

        streamer = threading.Thread(target=stream, daemon=True)
        streamer.start()
        time.sleep(0.3)
        try:
            ack = g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0)
        finally:
            stop.set()
            streamer.join()
        assert ack.result == M.MAV_RESULT_ACCEPTED
    finally:
        g.close()


def _upload_rest(g: Gcs, items, first) -> int:
    g.c.mav.send(items[first.seq])
    while True:
        m = g.recv(["MISSION_REQUEST_INT", "MISSION_ACK"], 5)
        assert m is not None, "vehicle stopped asking for items"
        if m.get_type() == "MISSION_ACK":
            return m.type
        g.c.mav.send(items[m.seq])


def test_position_mode_flies_on_manual_control_and_holds_when_it_stops(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        _take_off(g)
        time.sleep(0.5)

        def sticks(x: int, y: int, z: int, seconds: float) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                g.c.mav.manual_control_send(g.sysid, x, y, z, 0, 0)
                time.sleep(0.05)

        sticks(0, 0, 500, 0.2)
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 3, 0).result == M.MAV_RESULT_ACCEPTED
        start = sitl.vehicle.estimate().copy()
        sticks(1000, 0, 700, 0.4)  # full forward (north at yaw 0), some climb
        moved = sitl.vehicle.estimate() - start
        assert moved[0] > 1.0 and moved[2] < -0.2 and abs(moved[1]) < 0.5, moved
        sticks(0, 0, 500, 0.5)  # centred: stop and hold
        held = sitl.model.state.position_ned.copy()
        sticks(0, 0, 500, 0.3)
        assert np.linalg.norm(sitl.model.state.position_ned - held) < 0.2, "centred sticks hold position"
        hb = g.recv("HEARTBEAT", 3, lambda h: (h.custom_mode >> 16) & 0xFF == 4)  # sticks gone: AUTO.LOITER
        assert hb is not None and hb.custom_mode >> 24 == 3
        assert any("Manual control lost" in t for t in g.texts + sitl.vehicle.counters.statustext)
    finally:
        g.close()


def test_offboard_flies_the_last_setpoint_the_moment_it_is_entered(sitl_factory) -> None:
    """As PX4: setpoints streamed before OFFBOARD are held, and the latest is flown on the switch,
    not when the client's stream happens to send the next one (which tied the first metres after
    the switch to wall-clock timing: flights of one seed differed)."""
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        _take_off(g)
        start = sitl.vehicle.estimate().copy()
        ignore_vel_acc = 0b0000_1111_1111_1000
        for _ in range(3):  # the stream PX4 wants before OFFBOARD; then it stops
            g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, ignore_vel_acc,
                                                       start[0] + 5.0, start[1], start[2], 0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.02)
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0).result == M.MAV_RESULT_ACCEPTED
        t0 = sitl.t
        end = time.monotonic() + 5
        while time.monotonic() < end and sitl.t < t0 + 1.0:
            time.sleep(0.01)
        assert sitl.vehicle.mode == "OFFBOARD"
        assert sitl.vehicle.estimate()[0] - start[0] > 0.5, "flying to the setpoint with no new one sent"
    finally:
        g.close()


def test_streams_are_stamped_on_their_rate_lattice_whenever_asked_for(sitl_factory) -> None:
    """A stream's samples fall on the lattice of its period in simulated time (k / rate), not a
    period after whenever a client asked for it (a wall-clock race): a companion that reads the
    sample at its decision's instant then reads the same one in every run (on a loaded machine
    its LOCAL_POSITION_NED was stamped .92 in one run and .86 in another, and flight seed 2 flew
    60 or 24 moves)."""
    sitl = sitl_factory(physics="kinematic", speedup=4.0)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        for delay in (0.13, 0.37):  # asked for at two arbitrary instants
            time.sleep(delay)
            g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 100_000)
            stamps = []
            deadline = time.monotonic() + 5.0
            while len(stamps) < 12 and time.monotonic() < deadline:
                msg = g.recv("LOCAL_POSITION_NED", 1.0)
                if msg is not None:
                    stamps.append(msg.time_boot_ms)
            assert len(stamps) >= 12
            # the first may be the one sent when asked; the rest on the first tick at or after
            # each multiple of 100 ms (a stamp of 99 ms is 100 ms less rounding)
            phase = [ms % 100 for ms in stamps[2:]]
            assert all(p < 1000 * TICK_S or p >= 99 for p in phase), stamps
    finally:
        g.close()
