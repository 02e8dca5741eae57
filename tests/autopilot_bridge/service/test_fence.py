"""The companion's fence (autopilot_bridge/service/fence.py): the exact home test, the plan's checks,
and the pre-flight upload, read-back and enabling on our SITL in both dialects over UDP; the
pilot refuses to take off when home lies outside."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from bridge_pad import free_port, on_the_pad

from autopilot_bridge.camera import MavlinkCamera
from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.fence import (
    EXCLUSION,
    INCLUSION,
    BreachWatch,
    FenceBreached,
    FencePlan,
    FenceRefused,
    ensure_fence,
    locate,
    to_e7,
)
from autopilot_bridge.service.pilot import Pilot
from autopilot_bridge.service.search_data import SearchLog
from sim.mavlink import Sitl, SitlConfig


def _square(home, n0: float, e0: float, n1: float, e1: float) -> list[tuple[float, float]]:
    out = []
    for n, e in ((n0, e0), (n0, e1), (n1, e1), (n1, e0)):
        lat, lon, _ = home.ned_to_geodetic(np.array([n, e, 0.0]))
        out.append((lat, lon))
    return out


def test_locate_is_exact_on_a_concave_ring_its_edges_and_vertices() -> None:
    ell = [(0, 0), (0, 40), (20, 40), (20, 20), (40, 20), (40, 0)]  # an L
    assert locate((10, 10), ell) == 1 and locate((30, 10), ell) == 1 and locate((10, 30), ell) == 1
    assert locate((30, 30), ell) == -1, "the L's notch"
    assert locate((20, 30), ell) == 0 and locate((20, 20), ell) == 0 and locate((0, 0), ell) == 0
    assert locate((-1, 20), ell) == -1 and locate((41, 0), ell) == -1
    # one 1e-7 degree either side of an edge far from the origin: integers, no rounding
    big = [(514545000, -25879000), (514545000, -25870000), (514550000, -25870000), (514550000, -25879000)]
    assert locate((514545001, -25875000), big) == 1 and locate((514544999, -25875000), big) == -1


def test_plan_checks_its_polygons() -> None:
    sq = [(51.0, -2.0), (51.0, -1.9), (51.1, -1.9), (51.1, -2.0)]
    plan = FencePlan.of(sq + [sq[0]], [[(51.05, -1.95), (51.05, -1.94), (51.06, -1.94)]])
    assert len(plan.inclusion) == 4, "a closing vertex is dropped"
    assert [i[:2] for i in plan.items()] == [(INCLUSION, 4)] * 4 + [(EXCLUSION, 3)] * 3
    with pytest.raises(ValueError, match="inclusion polygon: a polygon needs at least 3 distinct vertices"):
        FencePlan.of(sq[:2])
    with pytest.raises(ValueError, match=r"exclusion polygon 0: vertex \(nan"):
        FencePlan.of(sq, [[(float("nan"), 0.0)] * 3])


def _sitl(dialect: str) -> Sitl:
    return Sitl(SitlConfig(dialect=dialect, ekf_delay_s=1.0, speedup=10.0, physics="kinematic", camera=False,
                           gcs_link=False, api_local_port=free_port(), api_remote_port=free_port())).start()


@pytest.mark.parametrize("dialect", ["px4", "ardupilot"])
def test_ensure_fence_uploads_reads_back_and_enables(dialect: str) -> None:
    sitl = _sitl(dialect)
    h = sitl.home
    plan = FencePlan.of(_square(h, -30, -30, 30, 30), [_square(h, 10, 10, 20, 20)])
    try:
        with VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}") as link:
            link.wait_heartbeat()
            link.request_streams()
            if dialect == "px4":
                assert link.set_param("GF_ACTION", 0) == 0
            lines = ensure_fence(link, plan)
            assert lines[0].startswith("fence: 8 vertices uploaded and read back")
            want = {"px4": ["GF_ACTION 0 -> 2"], "ardupilot": ["FENCE_ENABLE 0 -> 1"]}[dialect]
            assert [ln.split(" (")[0].removeprefix("fence: ") for ln in lines[1:]] == want
            v = sitl.vehicle
            assert [(it.x, it.y) for it in v.fences.items] == [(to_e7(a), to_e7(b)) for a, b in
                                                              plan.inclusion + plan.exclusions[0]]
            assert len(v.fences.zones) == 2
            assert ensure_fence(link, plan)[1:] == [], "again: nothing left to change"
            # a fence the vehicle cannot hold: its ACK, named
            many = FencePlan.of([(h.lat_deg + 1e-4 * np.cos(a), h.lon_deg + 1e-4 * np.sin(a))
                                 for a in np.linspace(0, 2 * np.pi, 80, endpoint=False)])
            with pytest.raises(FenceRefused, match="fence upload refused: MISSION_ACK MAV_MISSION_NO_SPACE"):
                ensure_fence(link, many)
    finally:
        sitl.stop()


def test_pilot_refuses_to_take_off_with_home_outside_the_fence() -> None:
    with on_the_pad(36) as pad:
        h = pad.sitl.home
        outside = FencePlan.of(_square(h, 5, 5, 40, 40))
        pilot = Pilot(pad.link, replace(pad.spec, fence=outside), pad.estimator, pad.intake, pad.reg, SearchLog(), MavlinkCamera(pad.link, discover_timeout_s=0.3))
        with pytest.raises(FenceRefused, match=r"^refusing to fly: home \(51\.\d{7}, -2\.\d{7}\) is outside the "
                                               "fence's inclusion polygon$"):
            pilot.take_off(timeout=10)
        assert not pad.sitl.model.state.armed and pad.sitl.vehicle.fences.items == [], "nothing flown, nothing sent"
        in_pond = FencePlan.of(_square(h, -30, -30, 30, 30), [_square(h, -3, -3, 3, 3)])
        with pytest.raises(FenceRefused, match="is inside the fence's exclusion polygon 0"):
            Pilot(pad.link, replace(pad.spec, fence=in_pond), pad.estimator, pad.intake, pad.reg, SearchLog(),
                  MavlinkCamera(pad.link, discover_timeout_s=0.3)).take_off(timeout=10)
        # in flight: a position seen outside stops the next leg (it would undo the fence's action)
        pilot.fence_watch = watch = BreachWatch(pad.link, in_pond)
        pad.link.wait_for(lambda: watch.outside is not None, 5, "a position in the pond")
        with pytest.raises(FenceBreached, match=r"^fence breached: the vehicle was at \(51\.\d+, -2\.\d+\), inside "
                                                "exclusion polygon 0; the companion flies no further legs$"):
            pilot.set_local(np.zeros(2))
        assert pilot.log.setpoints_local == [], "no setpoint went out"
        watch.close()


@pytest.mark.parametrize("name", ["farm_barn", "l_paddock_30deg", "pond_meadow"])
def test_an_example_fields_fence_goes_up_from_a_searchable_cell(name: str) -> None:
    from sim.field.model import load_field
    from sim.vehicle.geo import HomePosition

    field = load_field(Path(__file__).parents[3] / "examples" / "fields" / "out" / name / "field.json")
    plan = FencePlan.of_field(field)
    assert plan.inclusion == tuple(field.outer[:-1] if field.outer[-1] == field.outer[0] else field.outer)
    assert len(plan.exclusions) == len(field.no_fly)
    y, x = (int(v) for v in np.argwhere(field.mask)[len(np.argwhere(field.mask)) // 2])
    lat, lon = field.cell_to_latlon((x, y))
    sitl = Sitl(SitlConfig(home=HomePosition(lat, lon, 30.0), speedup=10.0, physics="kinematic", camera=False,
                           gcs_link=False, api_local_port=free_port(), api_remote_port=free_port())).start()
    try:
        with VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}") as link:
            link.wait_heartbeat()
            assert ensure_fence(link, plan)[0].startswith(f"fence: {len(plan.items())} vertices uploaded")
            assert len(sitl.vehicle.fences.zones) == 1 + len(field.no_fly), "PX4 kept every zone: home is inside"
    finally:
        sitl.stop()
