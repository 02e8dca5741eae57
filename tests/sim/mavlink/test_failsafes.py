"""Failsafes as PX4 names them, each driven to its action over MAVLink: offboard loss escalates
(COM_OBL_RC_ACT), data-link loss returns (NAV_DLL_ACT), the battery drains on both airframes
and returns then lands (COM_LOW_BAT_ACT), failure injection from MAVSDK's failure plugin, fence
and failsafe parameters locked while armed, HEARTBEAT cannot be switched off, and the geofence
reported in SYS_STATUS."""

from __future__ import annotations

import asyncio
import math
import threading
import time

import pytest
from plain_gcs import Gcs, M

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.policy_service import PolicyService, SearchSpec
from sim.mavlink.modes import px4_custom_mode


def _set(g: Gcs, name: str, value: float) -> float:
    g.c.mav.param_set_send(g.sysid, 1, name.encode(), value, M.MAV_PARAM_TYPE_REAL32)
    echo = g.recv("PARAM_VALUE", 3, lambda m: m.param_id == name)
    assert echo is not None
    return echo.param_value


def _airborne(g: Gcs) -> None:
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan).result == M.MAV_RESULT_ACCEPTED
    assert g.recv("EXTENDED_SYS_STATE", 10, lambda m: m.landed_state == M.MAV_LANDED_STATE_IN_AIR)


def _until(pred, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return pred()


def test_offboard_loss_holds_then_escalates_to_return(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        assert _set(g, "COM_FAIL_ACT_T", 1.0) == pytest.approx(1.0)
        _airborne(g)
        stop = threading.Event()

        def stream() -> None:
            while not stop.is_set():
                g.c.mav.set_position_target_local_ned_send(0, g.sysid, 1, M.MAV_FRAME_LOCAL_NED, 0b110111111000,
                                                           0, 0, -3.5, 0, 0, 0, 0, 0, 0, 0, 0)
                time.sleep(0.05)

        t = threading.Thread(target=stream)
        t.start()
        time.sleep(0.3)
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0).result == M.MAV_RESULT_ACCEPTED
        stop.set()
        t.join()
        assert _until(lambda: sitl.vehicle.mode == "AUTO.LOITER", 5), "held first"
        assert _until(lambda: sitl.vehicle.mode in ("AUTO.RTL", "AUTO.LAND"), 5), "then COM_OBL_RC_ACT: no sticks, return"
        assert any("COM_OBL_RC_ACT=0" in w for _, w in sitl.vehicle.failsafe_log), sitl.vehicle.failsafe_log
        assert _until(lambda: not sitl.model.state.armed, 30), "returned, landed and disarmed"
    finally:
        g.close()


def test_data_link_loss_returns_home(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        assert _set(g, "COM_DL_LOSS_T", 5.0) == pytest.approx(5.0)
        g.c.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
        _airborne(g)
        g.c.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
        t0 = time.monotonic()  # ... and then the ground station goes quiet
        assert _until(lambda: sitl.vehicle.mode == "AUTO.RTL", 9)
        assert time.monotonic() - t0 >= 4.5, "not before COM_DL_LOSS_T"
        assert any("NAV_DLL_ACT=2" in w for _, w in sitl.vehicle.failsafe_log)
    finally:
        g.close()


def test_a_hung_decision_loop_stops_the_setpoints_and_the_vehicle_returns(sitl_factory) -> None:
    """The companion's decision thread (here the test thread) stops making progress: its
    setpoint stream stops at the deadline, and the vehicle's offboard-loss failsafe fires."""
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    assert _set(g, "COM_FAIL_ACT_T", 1.0) == pytest.approx(1.0)
    g.close()
    link = VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}")
    service = PolicyService(link, policy=None, spec=SearchSpec(origin=sitl.field_origin))  # type: ignore[arg-type]
    try:
        service.take_off()
        assert link.telemetry.mode == "OFFBOARD" or _until(lambda: sitl.vehicle.mode == "OFFBOARD", 3)
        # hung: no pilot.expect() again; the stream's deadline (DECISION_DEADLINE_S) runs out
        assert _until(lambda: sitl.vehicle.mode == "AUTO.LOITER", 10)
        assert _until(lambda: sitl.vehicle.mode == "AUTO.RTL", 5)
        assert link.telemetry.heartbeat_time > 0
    finally:
        service.stop_setpoints()
        link.close()


@pytest.mark.parametrize("physics", ["kinematic", "pybullet"])
def test_battery_drains_on_both_airframes_then_returns_and_lands(sitl_factory, physics: str) -> None:
    sitl = sitl_factory(physics=physics, camera=False, speedup=10.0)
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        assert _set(g, "UAVS_BAT_ENDUR_S", 40.0) == pytest.approx(40.0)
        assert _set(g, "SIM_BAT_MIN_PCT", 0.0) == 0.0  # PX4 SITL's battery stops at 50 % by default
        full = g.recv("BATTERY_STATUS", 3)
        assert full.battery_remaining == 100
        _airborne(g)
        assert _until(lambda: len(sitl.vehicle.failsafe_log) >= 2, 30), sitl.vehicle.failsafe_log
        low = g.recv("BATTERY_STATUS", 10, lambda m: m.battery_remaining <= 8)
        assert low is not None and low.voltages[0] < full.voltages[0]
        assert g.recv("SYS_STATUS", 5, lambda m: m.battery_remaining <= 8) is not None
        assert _until(lambda: not sitl.model.state.armed, 40), sitl.vehicle.failsafe_log
        what = [w for _, w in sitl.vehicle.failsafe_log]
        assert what[0].startswith("battery low") and "critical" in what[1] and what[1].endswith("AUTO.RTL"), what
        assert what[2].startswith("battery emergency") or not sitl.model.state.armed, what
    finally:
        g.close()


def test_fence_and_failsafe_parameters_are_locked_while_armed(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        _airborne(g)
        for name, value in (("GF_MAX_HOR_DIST", 10000.0), ("NAV_DLL_ACT", 0.0), ("COM_LOW_BAT_ACT", 0.0)):
            before = sitl.vehicle.params[name]
            assert _set(g, name, value) == pytest.approx(before), f"{name} changed in flight"
        assert any("cannot change while armed" in t for t in sitl.vehicle.counters.statustext)
        assert _set(g, "NAV_ACC_RAD", 0.8) == pytest.approx(0.8), "ordinary parameters still change"
        assert _set(g, "NAV_DLL_ACT", 4.0) != 4.0
    finally:
        g.close()


def test_heartbeat_cannot_be_switched_off_and_sys_status_reports_the_fence(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        ack = g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_HEARTBEAT, -1)
        assert ack.result == M.MAV_RESULT_DENIED
        time.sleep(1.2)
        assert g.recv("HEARTBEAT", 2) is not None
        s = g.recv("SYS_STATUS", 3)
        fence = M.MAV_SYS_STATUS_GEOFENCE
        assert s.onboard_control_sensors_present & fence and s.onboard_control_sensors_enabled & fence
        assert s.onboard_control_sensors_health & fence, "no breach: healthy (MAVProxy showed a false breach)"
    finally:
        g.close()


def test_mavsdk_failure_plugin_drives_gps_and_battery_failures(sitl_factory) -> None:
    from mavsdk.asyncio import Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.failure import FailureAsync
    from mavsdk.asyncio.plugins.param import ParamAsync
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
    from mavsdk.plugins.failure import FailureType, FailureUnit

    sitl = sitl_factory(physics="kinematic")
    port = sitl.cfg.api_ports[1]
    async def scenario() -> None:
        m = Mavsdk(Configuration.create_manual(245, 190, True))
        try:
            await m.add_any_connection(f"udpin://0.0.0.0:{port}")
            system = await m.first_autopilot(timeout_s=15.0)
            par, fail, act, tel = ParamAsync(system), FailureAsync(system), ActionAsync(system), TelemetryAsync(system)
            await par.set_param_float("COM_DL_LOSS_T", 5.0)
            await par.set_param_float("SYS_FAILURE_EN", 1.0)
            for _ in range(50):
                if await tel.health_all_ok():
                    break
                await asyncio.sleep(0.1)
            await act.arm()
            await act.takeoff()
            for _ in range(100):
                if not sitl.model.state.landed:
                    break
                await asyncio.sleep(0.1)
            # GPS off in the air: no position, land
            await fail.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
            for _ in range(60):
                if sitl.vehicle.mode == "AUTO.LAND":
                    break
                await asyncio.sleep(0.1)
            assert sitl.vehicle.mode == "AUTO.LAND", sitl.vehicle.failsafe_log
            await fail.inject(FailureUnit.SENSOR_GPS, FailureType.OK, 0)
            await fail.inject(FailureUnit.SYSTEM_BATTERY, FailureType.OFF, 0)
            for _ in range(30):
                if sitl.vehicle.battery.reading == 0.0:
                    break
                await asyncio.sleep(0.1)
            assert sitl.vehicle.battery.reading == 0.0
        finally:
            m.destroy()

    asyncio.run(asyncio.wait_for(scenario(), 90))
    what = [w for _, w in sitl.vehicle.failsafe_log]
    assert any(w.startswith("GPS lost") for w in what)
    assert {"battery"} == sitl.vehicle.failures


def test_failure_injection_is_refused_unless_enabled(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        ack = g.command(M.MAV_CMD_INJECT_FAILURE, M.FAILURE_UNIT_SENSOR_GPS, M.FAILURE_TYPE_OFF, 0)
        assert ack.result == M.MAV_RESULT_DENIED and not sitl.vehicle.failures
        assert px4_custom_mode("AUTO.RTL")  # the mode encoding the failsafes report
    finally:
        g.close()


def test_injected_mavlink_signal_loss_fires_the_data_link_failsafe(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic")
    g = Gcs(sitl.cfg.gcs_ports[1])
    try:
        assert _set(g, "COM_DL_LOSS_T", 5.0) == 5.0 and _set(g, "SYS_FAILURE_EN", 1.0) == 1.0
        g.c.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
        _airborne(g)
        ack = g.command(M.MAV_CMD_INJECT_FAILURE, M.FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL, M.FAILURE_TYPE_OFF, 0)
        assert ack.result == M.MAV_RESULT_ACCEPTED, "the ACK goes out before the link fails"
        for _ in range(10):  # the ground station keeps heartbeating; the vehicle hears none of it
            g.c.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
            if sitl.vehicle.mode == "AUTO.RTL":
                break
            time.sleep(1.0)
        assert sitl.vehicle.mode == "AUTO.RTL", sitl.vehicle.failsafe_log
        assert g.command(M.MAV_CMD_INJECT_FAILURE, M.FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL, M.FAILURE_TYPE_OK, 0).result == 0
        assert not sitl.vehicle.failures
    finally:
        g.close()


def test_the_simulated_battery_stops_at_sim_bat_min_pct() -> None:
    """As PX4 SITL: a long simulated flight (wall-clock waits at high speedup add simulated
    minutes) must not end in a battery failsafe nobody asked for."""
    from sim.mavlink.battery import Battery
    from sim.mavlink.params import ParamStore

    b, p = Battery(), ParamStore()
    b.step(1e6, armed=True, in_air=True, endurance_s=p["UAVS_BAT_ENDUR_S"], min_remaining=p["SIM_BAT_MIN_PCT"] / 100)
    assert b.remaining == pytest.approx(0.5) and b.remaining > p["BAT_LOW_THR"]
    b.step(1e6, armed=True, in_air=True, endurance_s=1500.0, min_remaining=0.0)
    assert b.remaining == 0.0
