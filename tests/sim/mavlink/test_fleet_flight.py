"""`--count 16`: sixteen PyBullet vehicles in one process (one physics step, one vectorised
controller), two of them flown at once by two MAVSDK clients, each on its vehicle's own port."""

import asyncio

import numpy as np
import pytest
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from test_mavsdk_flight import _autopilot, _until
from udp_ports import free_udp_port

from sim.gridworld import cell_to_ned
from sim.mavlink import Sitl, SitlConfig, SitlFleet


def _fleet(n: int, physics: str, speedup: float) -> SitlFleet:
    cfgs = [SitlConfig(instance=i, physics=physics, speedup=speedup, camera=False, episode_seed=i, seed=i,
                       api_local_port=free_udp_port(), api_remote_port=free_udp_port(),
                       gcs_local_port=free_udp_port(), gcs_remote_port=free_udp_port()) for i in range(n)]
    return SitlFleet(cfgs)


@pytest.mark.slow
def test_two_mavsdk_clients_fly_two_of_sixteen_vehicles_at_once() -> None:
    fleet = _fleet(16, "pybullet", 4.0).start()
    flown = {3: (6.0, 0.0), 11: (0.0, -5.0)}  # vehicle -> (north, east) it is sent to

    async def fly(i: int, north: float, east: float) -> None:
        sitl = fleet[i]
        async with _autopilot(sitl.cfg.api_ports[1]) as system:
            tel, act = TelemetryAsync(system), ActionAsync(system)
            await _until(tel.health_all_ok, 20, f"vehicle {i} health")
            await act.arm()
            await act.set_takeoff_altitude(3.0)
            await act.takeoff()
            await _until(lambda: _true(-sitl.vehicle.estimate()[2] > 2.7), 30, f"vehicle {i} climbed")
            lat, lon, alt = sitl.home.ned_to_geodetic(np.array([north, east, -3.0]))
            await act.goto_location(lat, lon, alt, 0.0)
            await _until(lambda: _true(_dist(sitl, north, east) < 1.5), 40, f"vehicle {i} at its goal")
            await act.land()

            async def disarmed() -> bool:
                return not await tel.armed()

            await _until(disarmed, 40, f"vehicle {i} landed and disarmed")

    async def both() -> None:
        await asyncio.gather(*(fly(i, n, e) for i, (n, e) in flown.items()))

    try:
        asyncio.run(both())
        for i, (n, e) in flown.items():
            s = fleet[i].model.state
            assert s.landed and not s.armed
            assert _dist(fleet[i], n, e) < 1.5, "landed at its goal"
        for i, sitl in enumerate(fleet.sitls):
            if i not in flown:
                s = sitl.model.state
                assert s.landed and not s.armed and np.linalg.norm(s.position_ned) < 0.05, f"vehicle {i} stayed put"
        assert len({s.cfg.sysid for s in fleet.sitls}) == 16, "sixteen MAVLink systems"
    finally:
        fleet.stop()
    assert not fleet.errors and not any(s.errors for s in fleet.sitls)
    assert not any(s.vehicle.counters.handler_errors for s in fleet.sitls)


async def _true(x: bool) -> bool:
    return bool(x)


def _dist(sitl, north: float, east: float) -> float:
    """Horizontal distance from a goal in the frame the autopilot flies (its GPS estimate)."""
    return float(np.hypot(*(sitl.vehicle.estimate()[:2] - [north, east])))


def test_a_fleet_refuses_mixed_physics_and_shared_system_ids() -> None:
    a = SitlConfig(instance=1, physics="kinematic")
    with pytest.raises(ValueError, match="same physics"):
        SitlFleet([a, SitlConfig(instance=2, physics="pybullet")])
    with pytest.raises(ValueError, match="system ids"):
        SitlFleet([a, SitlConfig(instance=2, physics="kinematic", system_id=2)])


def test_fleet_cameras_see_what_lone_vehicles_see() -> None:
    """Each fleet vehicle renders its own field in a scene of its own: the same frames as a lone
    vehicle with the same config (the shared physics world holds every airframe)."""
    cfgs = [SitlConfig(instance=i, physics="pybullet", camera=True, episode_seed=i + 4, seed=i + 4,
                       api_local_port=free_udp_port(), api_remote_port=free_udp_port(),
                       gcs_local_port=free_udp_port(), gcs_remote_port=free_udp_port()) for i in range(2)]
    fleet = SitlFleet(cfgs)
    try:  # over each vehicle's first target
        where = [np.r_[cell_to_ned(s.target_cells()[0]) - s.spawn_ne, -3.5] for s in fleet.sitls]
        frames = [s._render(w, 0.0) for s, w in zip(fleet.sitls, where, strict=True)]
    finally:
        fleet.stop()
    for cfg, frame, w in zip(cfgs, frames, where, strict=True):
        grass = frame[0, 0]
        assert (np.abs(frame.astype(int) - grass).sum(axis=-1) > 60).sum() > 20, "a target in view"
        lone = Sitl(SitlConfig(**{**cfg.__dict__, "api_local_port": free_udp_port(),
                                  "gcs_local_port": free_udp_port()}))
        try:
            np.testing.assert_array_equal(frame, lone._render(w, 0.0))
        finally:
            lone.stop()
