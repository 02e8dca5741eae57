"""The vehicle speaking as ArduCopter (`SitlConfig(dialect="ardupilot")`), flown by a plain
pymavlink ground station over UDP: telemetry only when asked, arming only once the EKF has a
position (with ArduPilot's words for the refusal), GUIDED take-off, setpoints and landing,
GUIDED holding when its setpoints stop, and the GCS failsafe that only SYSID_MYGCS feeds."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from plain_gcs import Gcs, M
from pymavlink.dialects.v20 import ardupilotmega as apm

from sim.mavlink.dialects.ardupilot_modes import MODES, NAMES

POSITION_ONLY = 0x0DF8  # 3576: velocity, acceleration, yaw and yaw rate ignored


def _ap(sitl_factory, **kw):
    kw.setdefault("ekf_delay_s", 1.0)
    kw.setdefault("speedup", 10.0)
    sitl = sitl_factory(dialect="ardupilot", physics="kinematic", camera=False, **kw)
    return sitl, Gcs(sitl.cfg.gcs_ports[1])


def _until(pred, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return pred()


def _set_param(g: Gcs, name: str, value: float):
    g.c.mav.param_set_send(g.sysid, 1, name.encode(), value, M.MAV_PARAM_TYPE_REAL32)
    echo = g.recv("PARAM_VALUE", 3, lambda m: m.param_id == name)
    assert echo is not None, f"no PARAM_VALUE for {name}"
    return echo


def _mode(g: Gcs, name: str) -> int:
    return g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, MODES[name]).result


def _ready(g: Gcs, sitl, disarm_delay: float = 0.0) -> None:
    """GUIDED, the EKF ready, armed. disarm_delay: DISARM_DELAY (0: off, so a loaded machine's
    slow test cannot be disarmed on the ground between arming and NAV_TAKEOFF; 10 by default)."""
    assert _set_param(g, "DISARM_DELAY", disarm_delay).param_value == disarm_delay
    assert _mode(g, "GUIDED") == M.MAV_RESULT_ACCEPTED
    assert _until(lambda: sitl.vehicle.dialect.position_ok(sitl.vehicle.t, sitl.vehicle.fix), 5)
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED


def _airborne(g: Gcs, sitl, alt: float = 4.0) -> None:
    _ready(g, sitl)
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt).result == M.MAV_RESULT_ACCEPTED
    assert _until(lambda: -sitl.vehicle.estimate()[2] > alt - 0.3, 10), "climbed"


def _setpoint(g: Gcs, n: float, e: float, d: float) -> None:
    g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, POSITION_ONLY,
                                               n, e, d, 0, 0, 0, 0, 0, 0, 0, 0)


def _near(sitl, n: float, e: float, d: float, tol: float = 0.5) -> bool:
    p = sitl.vehicle.estimate()
    return math.dist(p.tolist(), [n, e, d]) < tol


def test_unasked_it_sends_heartbeats_only_until_a_stream_is_asked_for(sitl_factory) -> None:
    sitl, g = _ap(sitl_factory)
    try:
        hb = g.recv("HEARTBEAT", 3)
        assert (hb.autopilot, hb.type, hb.custom_mode) == (M.MAV_AUTOPILOT_ARDUPILOTMEGA, M.MAV_TYPE_QUADROTOR,
                                                          MODES["STABILIZE"])
        assert hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED and not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
        seen: dict[str, int] = {}
        # 16 simulated seconds at 10x; a loaded machine's vehicle runs slower than its speed-up
        # (the wall clock is the lower bound, the heartbeats and TIMESYNC the simulated one)
        start = time.monotonic()
        while time.monotonic() < start + 1.6 or (time.monotonic() < start + 8.0 and (
                seen.get("HEARTBEAT", 0) < 10 or seen.get("TIMESYNC", 0) < 1)):
            m = g.c.recv_match(blocking=True, timeout=0.2)
            if m is not None:
                seen[m.get_type()] = seen.get(m.get_type(), 0) + 1
        # as the real one: heartbeats, a TIMESYNC request every 10 s, the EKF origin and home once
        assert set(seen) <= {"HEARTBEAT", "STATUSTEXT", "TIMESYNC", "GPS_GLOBAL_ORIGIN", "HOME_POSITION"}, seen
        assert seen["HEARTBEAT"] >= 10 and seen.get("TIMESYNC", 0) >= 1, seen
        assert seen.get("GPS_GLOBAL_ORIGIN", 0) <= 1 and seen.get("HOME_POSITION", 0) <= 1, seen
        # one message by SET_MESSAGE_INTERVAL
        ack = g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 100_000)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        assert g.recv("GLOBAL_POSITION_INT", 3) is not None
        assert g.recv("ATTITUDE", 1) is None, "only what was asked for"
        # a group by REQUEST_DATA_STREAM: EXTRA3 carries SYSTEM_TIME and EKF_STATUS_REPORT
        g.c.mav.request_data_stream_send(g.sysid, 1, M.MAV_DATA_STREAM_EXTRA3, 4, 1)
        st = g.recv("SYSTEM_TIME", 3, lambda m: m.time_unix_usec > 0)
        assert st is not None and abs(st.time_unix_usec / 1e6 - time.time()) < 3600
        ekf = g.recv("EKF_STATUS_REPORT", 3)
        assert ekf is not None and ekf.flags & apm.EKF_POS_HORIZ_ABS and not ekf.flags & apm.EKF_CONST_POS_MODE
        g.c.mav.request_data_stream_send(g.sysid, 1, M.MAV_DATA_STREAM_EXTENDED_STATUS, 5, 1)
        gps = g.recv("GPS_RAW_INT", 3)
        # stamped with the boot time of the fix in whole ms (AP_GPS::send_mavlink_gps_raw), not UTC
        assert gps is not None and gps.time_usec % 1000 == 0 and gps.time_usec < 3600e6
        # unknown messages and commands, as ArduPilot answers them
        assert g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 9999, 100_000).result == M.MAV_RESULT_DENIED
        assert g.command(M.MAV_CMD_REQUEST_MESSAGE, 9999).result == M.MAV_RESULT_FAILED
        assert g.command(M.MAV_CMD_USER_1).result == M.MAV_RESULT_UNSUPPORTED
        assert g.command(M.MAV_CMD_INJECT_FAILURE, 1, 1).result == M.MAV_RESULT_UNSUPPORTED
        assert g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_HOME_POSITION).result == M.MAV_RESULT_ACCEPTED
        assert g.recv("HOME_POSITION", 3) is not None
    finally:
        g.close()


def test_arming_waits_for_the_ekf_position_and_says_why(sitl_factory) -> None:
    sitl, g = _ap(sitl_factory, ekf_delay_s=15.0)  # 1.5 s of wall time at 10x
    try:
        assert _mode(g, "GUIDED") == M.MAV_RESULT_ACCEPTED, "any mode while disarmed"
        g.c.mav.request_data_stream_send(g.sysid, 1, M.MAV_DATA_STREAM_EXTRA3, 4, 1)
        ekf = g.recv("EKF_STATUS_REPORT", 3)
        assert ekf.flags & apm.EKF_CONST_POS_MODE and not ekf.flags & apm.EKF_POS_HORIZ_ABS
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_FAILED
        assert _until(lambda: "Arm: Need Position Estimate" in sitl.vehicle.counters.statustext, 1)
        assert "Arm: Need Position Estimate" in g.texts or g.recv(
            "STATUSTEXT", 2, lambda m: m.text == "Arm: Need Position Estimate") is not None, "sent as STATUSTEXT"
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 5).result == M.MAV_RESULT_FAILED, "disarmed"
        assert g.recv("EKF_STATUS_REPORT", 5, lambda m: m.flags & apm.EKF_POS_HORIZ_ABS) is not None
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        assert g.recv("HEARTBEAT", 3, lambda m: m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED) is not None
        # RTL and LAND may not be armed in
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_ACCEPTED
        assert _mode(g, "RTL") == M.MAV_RESULT_ACCEPTED
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_FAILED
        assert _until(lambda: "Arm: RTL mode not armable" in sitl.vehicle.counters.statustext, 2)
    finally:
        g.close()


def test_guided_take_off_setpoints_land_and_disarm(sitl_factory) -> None:
    sitl, g = _ap(sitl_factory)
    try:
        _ready(g, sitl)
        assert _until(lambda: "Arming motors" in sitl.vehicle.counters.statustext, 1)
        # setpoints on the ground fly nothing: GUIDED takes off only on NAV_TAKEOFF
        _setpoint(g, 0, 0, -3)
        time.sleep(0.3)
        assert sitl.model.state.landed
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 4).result == M.MAV_RESULT_ACCEPTED
        assert _until(lambda: -sitl.vehicle.estimate()[2] > 3.7, 10)
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 6).result == M.MAV_RESULT_FAILED, "already flying"
        assert sitl.vehicle.mode == "GUIDED"
        _setpoint(g, 6, 4, -5)
        assert _until(lambda: _near(sitl, 6, 4, -5), 10), sitl.vehicle.estimate()
        # velocity-only setpoints fly, and stop after GUID_TIMEOUT without one
        g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, 0x0DC7,
                                                   0, 0, 0, -1.0, 0, 0, 0, 0, 0, 0, 0)
        assert _until(lambda: sitl.vehicle.estimate()[0] < 5.0, 5)
        assert _until(lambda: not sitl.vehicle._velocity_control, 6), "stopped after GUID_TIMEOUT"
        # DO_REPOSITION: COMMAND_INT only (COMMAND_LONG has no frame for it in ArduPilot)
        lat, lon, _ = sitl.home.ned_to_geodetic(np.array([2.0, 7.0, 0.0]))
        assert g.command(M.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, lat, lon, 5).result == M.MAV_RESULT_UNSUPPORTED
        g.c.mav.command_int_send(g.sysid, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_CMD_DO_REPOSITION, 0, 0,
                                 -1, 0, 0, 0, int(lat * 1e7), int(lon * 1e7), 5)
        ack = g.recv("COMMAND_ACK", 3, lambda a: a.command == M.MAV_CMD_DO_REPOSITION)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED
        assert _until(lambda: _near(sitl, 2, 7, -5), 10), sitl.vehicle.estimate()
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == M.MAV_RESULT_FAILED, "in the air"
        assert g.command(M.MAV_CMD_NAV_LAND).result == M.MAV_RESULT_ACCEPTED
        assert g.recv("HEARTBEAT", 3, lambda m: m.custom_mode == MODES["LAND"]) is not None
        assert _until(lambda: not sitl.model.state.armed, 15), "landed and disarmed"
        assert _until(lambda: "Disarming motors" in sitl.vehicle.counters.statustext, 2)
    finally:
        g.close()


def test_armed_on_the_ground_it_disarms_after_disarm_delay(sitl_factory) -> None:
    sitl, g = _ap(sitl_factory)
    try:
        _ready(g, sitl, disarm_delay=3)
        t0 = sitl.vehicle.t
        assert _until(lambda: not sitl.model.state.armed, 5)
        assert sitl.vehicle.t - t0 >= 2.9
    finally:
        g.close()


def _heartbeats(g: Gcs, stop: threading.Event, sysid: int | None = None) -> threading.Thread:
    """A ground station's 5 Hz heartbeat (from `sysid` when given), until stop is set."""
    mav = g.c.mav
    if sysid is not None:
        mav = apm.MAVLink(g.c, srcSystem=sysid, srcComponent=190)

    def run() -> None:
        while not stop.is_set():
            mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
            stop.wait(0.2)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def test_guided_holds_forever_when_setpoints_and_the_gcs_stop_with_fs_gcs_disabled(sitl_factory) -> None:
    sitl, g = _ap(sitl_factory)
    stop = threading.Event()
    try:
        assert _set_param(g, "FS_GCS_ENABLE", 0).param_value == 0  # the default
        assert _set_param(g, "FS_GCS_TIMEOUT", 2).param_value == 2
        beat = _heartbeats(g, stop)
        _airborne(g, sitl)
        _setpoint(g, 4, -3, -4)
        assert _until(lambda: _near(sitl, 4, -3, -4), 10)
        stop.set()  # the companion dies: no setpoints, no heartbeats
        beat.join()
        time.sleep(2.5)  # > FS_GCS_TIMEOUT of wall time, 25 simulated seconds
        assert sitl.vehicle.mode == "GUIDED" and sitl.model.state.armed and not sitl.model.state.landed
        assert _near(sitl, 4, -3, -4), "held the last target"
        assert not sitl.vehicle.failsafe_log
    finally:
        stop.set()
        g.close()


@pytest.mark.parametrize(("enable", "mode"), [(1, "RTL"), (5, "LAND")])
def test_the_gcs_failsafe_fires_when_sysid_mygcs_falls_silent(sitl_factory, enable: int, mode: str) -> None:
    sitl, g = _ap(sitl_factory)
    stop_mine, stop_other = threading.Event(), threading.Event()
    try:
        g.c.mav.param_request_read_send(g.sysid, 1, b"FS_GCS_ENABLE", -1)  # by name
        pv = g.recv("PARAM_VALUE", 3, lambda m: m.param_id == "FS_GCS_ENABLE")
        assert pv.param_value == 0 and pv.param_type == M.MAV_PARAM_TYPE_INT8, "ArduCopter's default and type"
        assert _set_param(g, "FS_GCS_ENABLE", enable).param_value == enable
        assert _set_param(g, "FS_GCS_TIMEOUT", 2).param_value == 2
        assert _set_param(g, "RTL_LOIT_TIME", 1000).param_value == 1000  # ms over home before landing (5000)
        assert _set_param(g, "RTL_ALT", 500).param_value == 500  # cm (1500): a shorter climb and descent
        mine = _heartbeats(g, stop_mine)  # system 255: SYSID_MYGCS
        _heartbeats(g, stop_other, sysid=200)  # another GCS: never feeds the failsafe
        _airborne(g, sitl)
        _setpoint(g, 5, 5, -4)
        assert _until(lambda: _near(sitl, 5, 5, -4), 10)
        assert sitl.vehicle.mode == "GUIDED"
        stop_mine.set()
        mine.join()
        t0 = time.monotonic()
        assert _until(lambda: sitl.vehicle.mode == mode, 6), sitl.vehicle.mode
        assert time.monotonic() - t0 >= 1.8, "not before FS_GCS_TIMEOUT"
        assert "GCS Failsafe" in sitl.vehicle.counters.statustext
        assert any(f"FS_GCS_ENABLE={enable}: {mode}" in w for _, w in sitl.vehicle.failsafe_log)
        assert g.recv("HEARTBEAT", 3, lambda m: m.custom_mode == MODES[mode]
                      and m.system_status == M.MAV_STATE_CRITICAL) is not None
        assert _until(lambda: not sitl.model.state.armed, 25), "landed (RTL: at home) and disarmed"
        if mode == "RTL":
            # over home in the estimate when it began to descend; the GPS bias drifts during the descent
            assert math.hypot(*sitl.model.state.position_ned[:2]) < 2.0, sitl.model.state.position_ned
    finally:
        stop_mine.set()
        stop_other.set()
        g.close()


def test_mode_numbers_round_trip(sitl_factory) -> None:
    assert {name: MODES[name] for name in ("STABILIZE", "ALT_HOLD", "AUTO", "GUIDED", "LOITER", "RTL", "LAND",
                                           "BRAKE")} == {"STABILIZE": 0, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4,
                                                         "LOITER": 5, "RTL": 6, "LAND": 9, "BRAKE": 17}
    assert all(NAMES[n] == name for name, n in MODES.items())
    sitl, g = _ap(sitl_factory)
    try:
        for name, number in MODES.items():  # disarmed: every mode may be entered
            assert _mode(g, name) == M.MAV_RESULT_ACCEPTED, name
            assert g.recv("HEARTBEAT", 3, lambda m, n=number: m.custom_mode == n) is not None, name
        g.c.mav.set_mode_send(g.sysid, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, MODES["LOITER"])
        assert g.recv("HEARTBEAT", 3, lambda m: m.custom_mode == MODES["LOITER"]) is not None
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 99).result == M.MAV_RESULT_FAILED
        assert _until(lambda: "No such mode 99" in sitl.vehicle.counters.statustext, 2)
    finally:
        g.close()


def test_sitl_dialect_option_is_recorded_in_the_field_file(tmp_path) -> None:
    """`uavsearch sitl --dialect ardupilot` writes "dialect" into the field file; a file from
    before dialects reads as px4; the two lists of dialect names agree."""
    import json

    from typer.testing import CliRunner

    from missions.cli import app
    from missions.fieldfile import DIALECTS as FIELD_DIALECTS
    from missions.fieldfile import FieldFileError, read_field
    from sim.mavlink.dialects import DIALECTS

    assert FIELD_DIALECTS == DIALECTS
    out = tmp_path / "f.json"
    r = CliRunner().invoke(app, ["sitl", "--instance", "37", "--physics", "kinematic", "--speedup", "0",
                                 "--duration", "1", "--dialect", "ardupilot", "--field-out", str(out)])
    assert r.exit_code == 0, r.output
    assert "ardupilot" in r.output and "udpin://0.0.0.0:14577" in r.output, "the same ports as px4"
    d = json.loads(out.read_text())
    assert d["dialect"] == "ardupilot" and d["provenance"]["sitl"]["dialect"] == "ardupilot"
    assert read_field(out).dialect == "ardupilot"
    del d["dialect"]
    out.write_text(json.dumps(d))
    assert read_field(out).dialect == "px4", "old files read as px4"
    out.write_text(json.dumps({**d, "dialect": "apm"}))
    with pytest.raises(FieldFileError, match="dialect"):
        read_field(out)


def test_a_fleet_of_ardupilot_vehicles_ticks_each_in_full() -> None:
    """`sitl --count N --dialect ardupilot`: quiet ticks and vectorised telemetry are PX4's, so
    each ArduPilot vehicle takes its full tick and builds its own HEARTBEAT."""
    from udp_ports import free_udp_port

    from sim.mavlink import SitlConfig, SitlFleet

    cfgs = [SitlConfig(instance=i, dialect="ardupilot", physics="kinematic", camera=False, speedup=0,
                       api_local_port=free_udp_port(), api_remote_port=free_udp_port(), gcs_link=False)
            for i in range(2)]
    fleet = SitlFleet(cfgs)
    try:
        fleet.run(duration=4.0)
        assert not fleet.errors and all(not s.errors for s in fleet.sitls)
        assert fleet.quiet.quiet_ticks == 0
        assert all(s.vehicle.dialect.ekf_announced and s.vehicle.mode == "STABILIZE" for s in fleet.sitls)
    finally:
        fleet.stop()


def test_arming_checks_on_simulated_time() -> None:
    """Stepped by hand (no thread, no client): STABILIZE arms once the attitude has settled
    (0.6 x ekf_delay_s), GUIDED once the EKF has its position; each refusal says why."""
    from udp_ports import free_udp_port

    from sim.mavlink import Sitl, SitlConfig
    from sim.mavlink.commands import Command

    sitl = Sitl(SitlConfig(dialect="ardupilot", physics="kinematic", camera=False, ekf_delay_s=10.0,
                           api_local_port=free_udp_port(), api_remote_port=free_udp_port(), gcs_link=False))
    v, arm, disarm = sitl.vehicle, Command(M.MAV_CMD_COMPONENT_ARM_DISARM, (1, 0, 0, 0, 0, 0, 0)), Command(
        M.MAV_CMD_COMPONENT_ARM_DISARM, (0, 0, 0, 0, 0, 0, 0))
    try:
        while sitl.t < 2.0:
            sitl.step()
        assert v.mode == "STABILIZE" and v.fix is not None
        assert v.dialect.execute(v, arm)[0] == M.MAV_RESULT_FAILED
        assert v.counters.statustext[-1] == "Arm: EKF attitude is bad"
        while sitl.t < 6.1:
            sitl.step()
        assert v.dialect.execute(v, arm)[0] == M.MAV_RESULT_ACCEPTED, v.counters.statustext[-3:]
        assert v.dialect.execute(v, disarm)[0] == M.MAV_RESULT_ACCEPTED
        assert v.dialect.change_mode(v, MODES["GUIDED"]) == M.MAV_RESULT_ACCEPTED
        assert v.dialect.execute(v, arm)[0] == M.MAV_RESULT_FAILED
        assert v.counters.statustext[-1] == "Arm: Need Position Estimate"
        while sitl.t < 10.1:
            sitl.step()
        assert "EKF3 IMU0 is using GPS" in v.counters.statustext
        assert v.dialect.execute(v, arm)[0] == M.MAV_RESULT_ACCEPTED
        assert v.dialect.change_mode(v, MODES["BRAKE"]) == M.MAV_RESULT_ACCEPTED
    finally:
        sitl._close()
