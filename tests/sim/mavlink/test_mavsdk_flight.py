"""The acceptance flight, driven by MAVSDK (the registry's mavsdk package, unmodified)."""

import asyncio
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import numpy as np
import pytest
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission import MissionAsync
from mavsdk.asyncio.plugins.offboard import OffboardAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.action import ActionError
from mavsdk.plugins.mission import MissionItem, MissionPlan
from mavsdk.plugins.offboard import PositionNedYaw
from mavsdk.plugins.telemetry import FlightMode


@asynccontextmanager
async def _autopilot(port: int) -> AsyncIterator:
    """A ground-station MAVSDK listening on `port`, and the first autopilot it discovers."""
    m = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        await m.add_any_connection(f"udpin://0.0.0.0:{port}")
        system = await m.first_autopilot(timeout_s=15.0)
        assert system is not None, "MAVSDK discovered no autopilot"
        yield system
    finally:
        m.destroy()


async def _until(pred, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not await pred():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.1)


def test_mavsdk_connect_health_arm_takeoff_mission_land_disarm(sitl_factory) -> None:
    sitl = sitl_factory(physics="pybullet", camera=False)
    port = sitl.cfg.api_ports[1]

    async def fly() -> dict:
        async with _autopilot(port) as system:
            tel, act, mis = TelemetryAsync(system), ActionAsync(system), MissionAsync(system)
            await _until(tel.health_all_ok, 15, "health all ok")
            h = await tel.health()
            assert all([h.is_gyrometer_calibration_ok, h.is_accelerometer_calibration_ok,
                        h.is_magnetometer_calibration_ok, h.is_local_position_ok, h.is_global_position_ok,
                        h.is_home_position_ok, h.is_armable]), h
            home = await tel.home()
            assert abs(home.latitude_deg - sitl.home.lat_deg) < 1e-6, "home as the vehicle set it"
            await act.arm()
            await _until(tel.armed, 5, "armed")
            await act.set_takeoff_altitude(3.5)
            await act.takeoff()
            await _until(tel.in_air, 15, "in air")
            pos = await tel.position()
            items = [
                MissionItem(
                    latitude_deg=home.latitude_deg + dn / 111_200.0,
                    longitude_deg=home.longitude_deg + de / (111_200.0 * np.cos(np.radians(home.latitude_deg))),
                    relative_altitude_m=3.5, speed_m_s=3.0, is_fly_through=False, acceptance_radius_m=0.5,
                    vehicle_action=MissionItem.VehicleAction.NONE,
                )
                for dn, de in [(8, 0), (8, 8), (0, 8), (0, 0)]
            ]
            await mis.upload_mission(MissionPlan(items))
            await mis.start_mission()
            visited, modes = [], set()

            async def finished() -> bool:
                visited.append(sitl.model.state.position_ned.copy())
                modes.add(await tel.flight_mode())
                return await mis.is_mission_finished()

            await _until(finished, 60, "mission finished")
            assert FlightMode.MISSION in modes, modes  # PX4's AUTO.MISSION, as MAVSDK decodes it
            # telemetry agrees with the physics (within the GPS error)
            pos = await tel.position()
            truth = sitl.model.state.position_ned
            reported = sitl.home.geodetic_to_ned(pos.latitude_deg, pos.longitude_deg, pos.absolute_altitude_m)
            await act.land()

            async def disarmed() -> bool:
                return not await tel.armed()

            await _until(disarmed, 30, "disarmed after landing")
            return {"visited": np.array(visited), "truth": truth, "reported": reported,
                    "landed": sitl.model.state.landed}

    r = asyncio.run(fly())
    assert np.linalg.norm(r["reported"][:2] - r["truth"][:2]) < 4.0
    v = r["visited"]
    for corner in ([8, 0], [8, 8], [0, 8]):
        assert np.min(np.linalg.norm(v[:, :2] - corner, axis=1)) < 1.0, f"flew past {corner}"
    assert r["landed"] and not sitl.model.state.armed


def _items(home, corners, alt: float) -> list[MissionItem]:
    return [
        MissionItem(
            latitude_deg=home.latitude_deg + dn / 111_200.0,
            longitude_deg=home.longitude_deg + de / (111_200.0 * np.cos(np.radians(home.latitude_deg))),
            relative_altitude_m=alt, speed_m_s=3.0, is_fly_through=True, acceptance_radius_m=1.0,
            vehicle_action=MissionItem.VehicleAction.NONE,
        )
        for dn, de in corners
    ]


def test_mavsdk_params_mission_download_geofence_offboard_and_return(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", speedup=8.0)
    port = sitl.cfg.api_ports[1]

    async def fly() -> None:
        async with _autopilot(port) as system:
            tel, act, mis = TelemetryAsync(system), ActionAsync(system), MissionAsync(system)
            par, off = ParamAsync(system), OffboardAsync(system)
            await _until(tel.health_all_ok, 15, "health all ok")
            # parameters
            assert await par.get_param_float("NAV_ACC_RAD") == pytest.approx(0.4)
            await par.set_param_float("NAV_ACC_RAD", 0.6)
            assert await par.get_param_float("NAV_ACC_RAD") == pytest.approx(0.6)
            assert sitl.vehicle.params["NAV_ACC_RAD"] == pytest.approx(0.6)
            # mission download equals upload
            home = await tel.home()
            plan = MissionPlan(_items(home, [(5, 0), (5, 5), (0, 5)], 4.0))
            await mis.upload_mission(plan)
            got = (await mis.download_mission()).mission_items
            assert [(round(i.latitude_deg, 7), round(i.longitude_deg, 7), i.relative_altitude_m) for i in got] == \
                [(round(i.latitude_deg, 7), round(i.longitude_deg, 7), i.relative_altitude_m) for i in plan.mission_items]
            # the geofence refuses a far goto, and MAVSDK hears it
            await act.arm()
            await act.takeoff()
            await _until(tel.in_air, 15, "in air")
            with pytest.raises(ActionError):
                await act.goto_location(home.latitude_deg + 500 / 111_200.0, home.longitude_deg,
                                        home.absolute_altitude_m + 4.0, 0.0)
            # offboard position setpoints (MAVSDK streams them at 20 Hz)
            await off.set_position_ned(PositionNedYaw(6.0, -3.0, -4.0, 0.0))
            await off.start()

            async def there() -> bool:
                return bool(np.linalg.norm(sitl.vehicle.estimate() - [6.0, -3.0, -4.0]) < 0.3)

            await _until(there, 15, "offboard setpoint reached")
            assert await tel.flight_mode() == FlightMode.OFFBOARD
            await off.stop()
            await act.return_to_launch()

            async def disarmed() -> bool:
                return not await tel.armed()

            await _until(disarmed, 30, "landed and disarmed after RTL")
            assert np.hypot(*sitl.vehicle.estimate()[:2]) < 1.0, "back over home"

    asyncio.run(fly())
    assert sitl.vehicle.counters.fence_rejections >= 1
