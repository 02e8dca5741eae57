"""Polygon fences on the SITL vehicle, over UDP: uploaded as MAVProxy's fence module does (its
items read by pymavlink's mavwp from a QGC WPL fence file) and by MAVSDK's geofence plugin,
read back, and enforced (a setpoint outside the polygon -> the dialect's fence action, a
STATUSTEXT, SYS_STATUS's geofence health bit); bad uploads get the real autopilots' answers."""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path

import numpy as np
import pytest
from plain_gcs import Gcs, M
from pymavlink import mavwp

from sim.mavlink.dialects.ardupilot_modes import MODES as AP_MODES

FENCE = M.MAV_MISSION_TYPE_FENCE
INC, EXC = M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
VEL_NORTH = 0b0000_1101_1100_0111  # position, acceleration, yaw, yaw rate ignored
POSITION_ONLY = 0x0DF8


def _ne_to_ll(home, n: float, e: float) -> tuple[float, float]:
    lat, lon, _ = home.ned_to_geodetic(np.array([n, e, 0.0]))
    return lat, lon


def _square(home, n0: float, e0: float, n1: float, e1: float) -> list[tuple[float, float]]:
    return [_ne_to_ll(home, n, e) for n, e in ((n0, e0), (n0, e1), (n1, e1), (n1, e0))]


def _fence_file(path: Path, home) -> Path:
    """A QGC WPL 110 fence file as MAVProxy's `fence save` writes it: a 30 m square round home
    (inclusion) with a 10 m square exclusion in its north-east quarter."""
    lines = ["QGC WPL 110"]
    polys = [(INC, _square(home, -30, -30, 30, 30)), (EXC, _square(home, 10, 10, 20, 20))]
    seq = 0
    for cmd, pts in polys:
        for lat, lon in pts:
            lines.append("\t".join(str(v) for v in (seq, 0, M.MAV_FRAME_GLOBAL, cmd, len(pts), 0, 0, 0,
                                                     f"{lat:.8f}", f"{lon:.8f}", 0, 1)))
            seq += 1
    path.write_text("\n".join(lines) + "\n")
    return path


def _mavproxy_items(g: Gcs, path: Path) -> list:
    """The file's items as MAVProxy sends them (mission_item_protocol's wp_to_mission_item_int:
    degrees * 1e7, truncated)."""
    loader = mavwp.MissionItemProtocol_Fence(g.sysid, 1)
    loader.load(str(path))
    out = []
    for i in range(loader.count()):
        w = loader.item(i)
        out.append(g.c.mav.mission_item_int_encode(
            w.target_system, w.target_component, w.seq, w.frame, w.command, w.current, w.autocontinue, w.param1,
            w.param2, w.param3, w.param4, int(w.x * 1.0e7), int(w.y * 1.0e7), w.z, FENCE))
    return out


def _upload(g: Gcs, items: list, count: int | None = None, skip: set[int] | None = None):
    """MAVProxy's transfer: COUNT, then each requested item as MISSION_ITEM_INT; the ACK's result
    (None: the vehicle fell silent) and the requests it sent."""
    g.c.mav.mission_count_send(g.sysid, 1, len(items) if count is None else count, FENCE)
    requests = []
    while True:
        m = g.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], 3,
                   lambda m: m.mission_type == FENCE)
        if m is None or m.get_type() == "MISSION_ACK":
            return (None if m is None else m.type), requests
        requests.append((m.get_type(), m.seq))
        if skip and m.seq in skip:
            skip.discard(m.seq)
            continue
        it = items[m.seq]
        g.c.mav.mission_item_int_send(g.sysid, 1, m.seq, it.frame, it.command, 0, 0, it.param1, it.param2, it.param3,
                                      it.param4, it.x, it.y, it.z, FENCE)


def _item(g: Gcs, seq: int, cmd: int, n_vertices: float, lat: float, lon: float, frame=M.MAV_FRAME_GLOBAL, z=0.0):
    return g.c.mav.mission_item_int_encode(g.sysid, 1, seq, frame, cmd, 0, 0, n_vertices, 0, 0, 0,
                                           int(round(lat * 1e7)), int(round(lon * 1e7)), z, FENCE)


def _download(g: Gcs) -> list:
    g.c.mav.mission_request_list_send(g.sysid, 1, FENCE)
    count = g.recv("MISSION_COUNT", 3, lambda m: m.mission_type == FENCE).count
    out = []
    for seq in range(count):
        g.c.mav.mission_request_int_send(g.sysid, 1, seq, FENCE)
        out.append(g.recv("MISSION_ITEM_INT", 3, lambda m, s=seq: m.seq == s and m.mission_type == FENCE))
    g.c.mav.mission_ack_send(g.sysid, 1, M.MAV_MISSION_ACCEPTED, FENCE)
    return out


def _said(g: Gcs, text: str, timeout: float = 3.0) -> bool:
    """The vehicle sent this STATUSTEXT (already, while something else was awaited, or now)."""
    return text in g.texts or g.recv("STATUSTEXT", timeout, lambda m: m.text == text) is not None


def _until(pred, timeout: float, g: Gcs | None = None) -> bool:
    """Wait for pred, reading the ground station's socket meanwhile (g: a PX4 vehicle's telemetry
    at 10x fills an unread socket in a second or two, and the STATUSTEXT after it is dropped)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        if g is None:
            time.sleep(0.05)
        else:
            g.recv("NO_SUCH_MESSAGE", 0.05)
    return pred()


def _same(items: list, got: list) -> None:
    assert [(m.command, m.param1, m.x, m.y) for m in got] == [(i.command, i.param1, i.x, i.y) for i in items]


def test_px4_fence_from_a_mavproxy_file_round_trip_and_hold_on_breach(sitl_factory, tmp_path) -> None:
    sitl = sitl_factory(physics="kinematic", camera=False, speedup=10.0)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        items = _mavproxy_items(g, _fence_file(tmp_path / "fence.txt", sitl.home))
        result, requests = _upload(g, items)
        assert result == M.MAV_MISSION_ACCEPTED
        assert requests == [("MISSION_REQUEST_INT", i) for i in range(8)], "PX4 asks with MISSION_REQUEST_INT"
        got = _download(g)
        _same(items, got)
        assert {m.frame for m in got} == {M.MAV_FRAME_GLOBAL_INT}, "PX4 reads fence points back in GLOBAL_INT"
        assert [z.command for z in sitl.vehicle.fences.zones] == [INC, EXC]
        # fly: take off, then an offboard setpoint 60 m north (inside the 100 m cylinder, outside the polygon)
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan).result == 0
        assert _until(lambda: -sitl.vehicle.estimate()[2] > 3.0, 10, g)
        g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, POSITION_ONLY,
                                                   60, 0, -3.5, 0, 0, 0, 0, 0, 0, 0, 0)
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0).result == 0
        assert _until(lambda: sitl.vehicle.mode == "AUTO.LOITER", 10, g), sitl.vehicle.mode
        n = float(sitl.vehicle.estimate()[0])
        assert 30.0 < n < 34.0, f"held just past the fence's north edge (30 m), at {n:.1f} m"
        assert _said(g, "Geofence: approaching or outside geofence")
        st = g.recv("SYS_STATUS", 3)
        assert not st.onboard_control_sensors_health & M.MAV_SYS_STATUS_GEOFENCE, "the breach in SYS_STATUS"
        assert any("geofence breach, GF_ACTION 2" in w for _, w in sitl.vehicle.failsafe_log)
    finally:
        g.close()


def test_px4_bad_fence_uploads_get_px4s_answers(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", camera=False, gcs_link=True)
    g = Gcs(sitl.cfg.gcs_ports[1])
    h = sitl.home
    sq = _square(h, -30, -30, 30, 30)
    try:
        good = [_item(g, i, INC, 4, *p) for i, p in enumerate(sq)]
        assert _upload(g, good, count=65)[0] == M.MAV_MISSION_NO_SPACE  # DM_KEY_FENCE_POINTS_MAX 64
        assert _upload(g, [_item(g, i, INC, 2, *p) for i, p in enumerate(sq)])[0] == M.MAV_MISSION_ERROR
        assert _upload(g, [_item(g, i, INC, 4, *p, z=10.0) for i, p in enumerate(sq)])[0] == M.MAV_MISSION_INVALID_PARAM7
        local = [_item(g, i, INC, 4, *p, frame=M.MAV_FRAME_LOCAL_NED) for i, p in enumerate(sq)]
        assert _upload(g, local)[0] == M.MAV_MISSION_UNSUPPORTED_FRAME
        # an item out of order is ignored: the vehicle asks for the one it wants again
        result, requests = _upload(g, good, skip={1})
        assert result == M.MAV_MISSION_ACCEPTED and requests[:3] == [("MISSION_REQUEST_INT", 0)] + [
            ("MISSION_REQUEST_INT", 1)] * 2, requests
        # a polygon that leaves out home is dropped when loaded
        away = [_item(g, i, INC, 4, *p) for i, p in enumerate(_square(h, 40, 40, 60, 60))]
        assert _upload(g, away)[0] == M.MAV_MISSION_ACCEPTED
        assert sitl.vehicle.fences.zones == [] and len(sitl.vehicle.fences.items) == 4
        assert _said(g, "Geofence invalid, doesn't contain Home position\t")
        # the ground station falls silent mid-upload: dropped after the timeout, without an ACK
        sitl.vehicle.missions.fences.TIMEOUT_S = 0.5
        g.c.mav.mission_count_send(g.sysid, 1, 4, FENCE)
        assert _said(g, "Mission sync timeout\t")
        assert sitl.vehicle.missions.fences.incoming is None
    finally:
        g.close()


def _ap(sitl_factory):
    sitl = sitl_factory(dialect="ardupilot", physics="kinematic", camera=False, ekf_delay_s=1.0, speedup=10.0)
    return sitl, Gcs(sitl.cfg.gcs_ports[1])


def test_ardupilot_fence_round_trip_refusal_and_rtl_on_breach(sitl_factory, tmp_path) -> None:
    sitl, g = _ap(sitl_factory)
    try:
        items = _mavproxy_items(g, _fence_file(tmp_path / "fence.txt", sitl.home))
        result, requests = _upload(g, items)
        assert result == M.MAV_MISSION_ACCEPTED
        assert {r[0] for r in requests} == {"MISSION_REQUEST"}, "ArduPilot asks with MISSION_REQUEST"
        got = _download(g)
        _same(items, got)
        assert {(m.frame, m.z) for m in got} == {(M.MAV_FRAME_GLOBAL, 0.0)}
        for seq, result in ((8, M.MAV_MISSION_ERROR), (9, M.MAV_MISSION_INVALID_SEQUENCE)):  # as the real one
            g.c.mav.mission_request_int_send(g.sysid, 1, seq, FENCE)
            assert g.recv("MISSION_ACK", 3).type == result
        for name, value in (("FENCE_ENABLE", 1), ("DISARM_DELAY", 0)):
            g.c.mav.param_set_send(g.sysid, 1, name.encode(), value, M.MAV_PARAM_TYPE_INT8)
            assert g.recv("PARAM_VALUE", 3, lambda m, n=name: m.param_id == n).param_value == value
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, AP_MODES["GUIDED"]).result == 0
        v = sitl.vehicle
        assert _until(lambda: v.dialect.position_ok(v.t, v.fix), 5)
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 4.0).result == M.MAV_RESULT_ACCEPTED
        assert _until(lambda: -v.estimate()[2] > 3.7, 10)
        # a GUIDED target in the exclusion zone is refused (check_destination_within_fence)
        g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, POSITION_ONLY,
                                                   15, 15, -4, 0, 0, 0, 0, 0, 0, 0, 0)
        assert _said(g, "Geofence: guided setpoint rejected")
        # flown out under velocity control: "Fence Breached", RTL
        for _ in range(60):
            g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, VEL_NORTH,
                                                       0, 0, 0, 5.0, 0, 0, 0, 0, 0, 0, 0)
            if v.mode == "RTL":
                break
            time.sleep(0.05)
        assert v.mode == "RTL", v.mode
        assert 30.0 < v.estimate()[0] < 33.0
        assert _said(g, "Fence Breached")
    finally:
        g.close()


def test_ardupilot_bad_fence_uploads_get_arducopters_answers(sitl_factory) -> None:
    sitl, g = _ap(sitl_factory)
    sq = _square(sitl.home, -30, -30, 30, 30)
    try:
        good = [_item(g, i, INC, 4, *p) for i, p in enumerate(sq)]
        assert _upload(g, good, count=71)[0] == M.MAV_MISSION_NO_SPACE
        assert _said(g, "Only 70 items are supported")
        # out of order: INVALID_SEQUENCE, and the upload goes on
        g.c.mav.mission_count_send(g.sysid, 1, 4, FENCE)
        assert g.recv("MISSION_REQUEST", 3).seq == 0
        g.c.mav.send(good[2])
        assert g.recv("MISSION_ACK", 3).type == M.MAV_MISSION_INVALID_SEQUENCE
        assert _upload(g, good)[0] == M.MAV_MISSION_ACCEPTED
        # validated at the end: a vertex count that changes mid-polygon
        bad = [_item(g, i, INC, 5 if i == 2 else 4, *p) for i, p in enumerate(sq)]
        assert _upload(g, bad)[0] == M.MAV_MISSION_ERROR
        assert _said(g, "Fence validation failed") and _said(g, "Unexpected vertex count want=4 got=5\n")
        assert len(sitl.vehicle.fences.items) == 4, "the fence before stays"
        wp = [_item(g, 0, M.MAV_CMD_NAV_WAYPOINT, 0, *sq[0])]
        assert _upload(g, wp)[0] == M.MAV_MISSION_UNSUPPORTED
        # silence mid-upload: "Fence upload timeout", OPERATION_CANCELLED
        sitl.vehicle.missions.fences.TIMEOUT_S = 0.5
        g.c.mav.mission_count_send(g.sysid, 1, 4, FENCE)
        ack = g.recv("MISSION_ACK", 3, lambda m: m.type != 0)
        assert ack.type == M.MAV_MISSION_OPERATION_CANCELLED and "Fence upload timeout" in g.texts
    finally:
        g.close()


@pytest.mark.parametrize("dialect", ["px4", "ardupilot"])
def test_mavsdk_geofence_plugin_uploads_and_downloads(sitl_factory, dialect: str) -> None:
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.geofence import GeofenceAsync
    from mavsdk.plugins.geofence import Circle, FenceType, GeofenceData, Point, Polygon

    sitl = sitl_factory(physics="kinematic", camera=False, dialect=dialect)
    port = sitl.cfg.api_ports[1]
    inc = _square(sitl.home, -30, -30, 30, 30)
    exc = _square(sitl.home, 10, 10, 20, 20)
    centre = _ne_to_ll(sitl.home, -15, -15)

    async def run():
        m = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            await m.add_any_connection(f"udpin://0.0.0.0:{port}")
            system = await m.first_autopilot(timeout_s=15.0)
            fence = GeofenceAsync(system)
            data = GeofenceData(
                polygons=[Polygon([Point(*p) for p in inc], FenceType.INCLUSION),
                          Polygon([Point(*p) for p in exc], FenceType.EXCLUSION)],
                circles=[Circle(Point(*centre), 5.0, FenceType.EXCLUSION)])
            await fence.upload_geofence(data)
            return await fence.download_geofence()
        finally:
            m.destroy()

    got = asyncio.run(run())
    assert [(p.fence_type, len(p.points)) for p in got.polygons] == [(FenceType.INCLUSION, 4), (FenceType.EXCLUSION, 4)]
    for poly, want in zip(got.polygons, (inc, exc), strict=True):
        for pt, (lat, lon) in zip(poly.points, want, strict=True):
            assert abs(pt.latitude_deg - lat) <= 1e-7 and abs(pt.longitude_deg - lon) <= 1e-7
    assert len(got.circles) == 1 and abs(got.circles[0].radius - 5.0) < 1e-6
    assert [z.command for z in sitl.vehicle.fences.zones] == [INC, EXC, M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION]
