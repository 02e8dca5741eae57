"""The companion computer flying a search over real MAVLink against the PyBullet SITL vehicle,
scored against the simulator's truth."""

import json
from pathlib import Path

import numpy as np
from bridge_pad import free_port
from pymavlink import mavutil

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.localisation.telemetry import READING_SD_M
from autopilot_bridge.service.policy_service import PolicyService, SearchSpec
from missions.flight import fly_search
from missions.flight_policy import flight_policy
from sim.gridworld import GridConfig, cell_to_ned
from sim.mavlink import Sitl, SitlConfig


def test_policy_service_flies_a_search_and_lands(tmp_path: Path) -> None:
    grid = GridConfig(n_targets=5)
    r = fly_search(tmp_path, seed=3, speedup=12.0, grid=grid, instance=21, max_moves=25)
    assert r["error"] is None, r["error"]
    assert 1 <= r["moves"] <= 25
    assert r["frames"] == r["moves"] + 1 and r["frames_missing"] == 0, "one camera frame per decision"
    # a target is found once, under the camera: seen again from the next cell with the posterior
    # a metre off it was counted twice (20 flights: every flight believed 5/5, 84 % truly found)
    assert r["believed_found"] <= r["truly_found"], "no target found twice or where the camera is not"
    log = json.loads((tmp_path / "search_log.json").read_text())
    steps = [abs(a[0] - b[0]) + abs(a[1] - b[1]) for a, b in zip(log["cells"], log["cells"][1:], strict=False)]
    assert set(steps) == {1}, "one grid move per decision"
    assert (tmp_path / "search.png").read_bytes()[:4] == b"\x89PNG"
    tlog = mavutil.mavlink_connection(str(tmp_path / "flight.tlog"))
    kinds, frame_from, asks_to = set(), set(), set()
    while (m := tlog.recv_match()) is not None:
        kinds.add(m.get_type())
        if m.get_type() == "ENCAPSULATED_DATA":
            frame_from.add(m.get_srcComponent())
        elif m.get_type() == "COMMAND_LONG" and m.command == mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE and m.param1 == 130:
            asks_to.add(m.target_component)
    assert {"SET_POSITION_TARGET_LOCAL_NED", "ENCAPSULATED_DATA", "COMMAND_LONG"} <= kinds
    # the frames came from the camera component on the vehicle's link, asked of it, not of the autopilot
    assert frame_from == {mavutil.mavlink.MAV_COMP_ID_CAMERA} and asks_to == {mavutil.mavlink.MAV_COMP_ID_CAMERA}


def test_centring_into_the_next_cell_moves_the_search_there() -> None:
    """PolicyService._centred_cell, on a real vehicle's link: after centring on a target, where
    the posterior is sure the camera is over the next cell the search goes on from that cell;
    where it is not sure, from the cell the policy chose."""
    grid = GridConfig()
    sitl = Sitl(SitlConfig(instance=30, speedup=4.0, physics="kinematic", camera=False, gcs_link=False,
                           api_local_port=free_port(), api_remote_port=free_port(), grid=grid)).start()
    link = VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}")
    try:
        svc = PolicyService(link, flight_policy("belief", None, grid, 0), SearchSpec(origin=sitl.field_origin, grid=grid))
        link.wait_heartbeat()
        # home too (HOME_POSITION at 0.5 Hz: the first may go out before this link listens)
        link.wait_for(lambda: len(svc.intake.local_history) > 5 and svc.intake.has_fixes() and bool(link.telemetry.home),
                      20, "telemetry")
        t = svc.intake.local_history[-1][0]
        svc.intake.fuse_until(t)
        assert svc.intake.fuse_reading(t, READING_SD_M)  # as at every decision: the autopilot's estimate
        cell = np.array([int(v) for v in sitl.episode.agent[0]])
        nxt = cell + (1 if cell[0] < grid.width - 1 else -1, 0)
        start = (svc.estimator._logw.copy(), svc.estimator._x.copy(), svc.estimator._p.copy())
        # registered on a target: the camera truly over the next cell's centre
        svc.estimator.doubt_split(3.0)
        for _ in range(3):
            svc.estimator.observe_position(t, cell_to_ned(nxt), 0.05)
        assert tuple(svc._centred_cell(t, cell)) == tuple(nxt)
        assert svc.log.centred_into_next == 1
        # the same position, but known to a metre only: not sure, the chosen cell stays
        svc.estimator._logw, svc.estimator._x, svc.estimator._p = start
        svc.estimator.doubt_split(1.0)
        svc.estimator.observe_position(t, cell_to_ned(cell + (nxt - cell) * 0.6), 1.0)
        assert tuple(svc._centred_cell(t, cell)) == tuple(cell)
        assert svc.log.centred_into_next == 1
    finally:
        link.close()
        sitl.stop()
