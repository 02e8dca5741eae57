"""Quiet ticks (sim/mavlink/quiet.py) change nothing: a fleet that skips the per-vehicle tick
where it would only drain the battery flies, streams and fails safe exactly as a fleet that
ticks every vehicle in full, tick by tick, on the same (fake) wall clock."""

from __future__ import annotations

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink
from udp_ports import free_udp_port

from sim.mavlink import SitlConfig, SitlFleet

M = mavlink
N = 5
SECONDS = 22.0


class FakeWall:
    """The vehicles' wall clock, moved by the test: the same for both fleets, so timers that
    wait on a client (offboard and data-link loss) fire on the same tick in both."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def _fleet(quiet: bool, wall: FakeWall, physics: str = "kinematic") -> tuple[SitlFleet, list[list[bytes]]]:
    cfgs = [SitlConfig(instance=i, physics=physics, speedup=0, camera=False, seed=i, episode_seed=i,
                       api_local_port=free_udp_port(), api_remote_port=free_udp_port(),
                       gcs_local_port=free_udp_port(), gcs_remote_port=free_udp_port()) for i in range(N)]
    fleet = SitlFleet(cfgs, quiet_ticks=quiet, vector_telemetry=quiet)
    fleet.quiet.clock = wall
    sent: list[list[bytes]] = []
    for s in fleet.sitls:
        v = s.vehicle
        v.clock = v.missions.clock = wall
        for link in v.links:
            link.clock = wall
        out: list[bytes] = []
        sent.append(out)
        for link in v.links:  # record every datagram instead of sending it
            link._sendto_peers = lambda buf, out=out: out.append(bytes(buf))
        for name, value in (("UAVS_BAT_ENDUR_S", 14.0 if s.cfg.instance == 0 else 1500.0),
                            ("SIM_BAT_MIN_PCT", 0.0), ("COM_OF_LOSS_T", 0.3), ("COM_FAIL_ACT_T", 0.0),
                            ("COM_DL_LOSS_T", 5.0), ("GF_MAX_HOR_DIST", 5.0 if s.cfg.instance == 4 else 100.0)):
            assert v.params.set(name, value)[0]
    return fleet, sent


def _script(k: int, home_alt: float) -> dict[int, list]:
    """Messages each vehicle receives at tick k (as a ground station or companion sends them):
    0 takes off and hovers until its battery fails it safe; 1 flies OFFBOARD, then its
    setpoints stop; 2 is watched by a ground station that goes silent; 3 stays on the ground;
    4 holds OFFBOARD 1 cm inside a 5 m geofence, so a GPS fix moving its estimate breaches it
    (a fix taken on a quiet tick that then must be full)."""
    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    t = k * 0.02
    out: dict[int, list] = {i: [] for i in range(N)}
    if k == 5:
        for i in (0, 1, 2, 4):
            out[i].append(gcs.command_long_encode(i + 1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
            out[i].append(gcs.command_long_encode(i + 1, 1, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0,
                                                  home_alt + 3.0))
    if 4.0 <= t < 9.0 and k % 10 == 0:  # setpoints at 5 Hz, then silence
        out[1].append(gcs.set_position_target_local_ned_encode(int(t * 1000), 2, 1, M.MAV_FRAME_LOCAL_NED, 0xBF8,
                                                               5.0, 3.0, -3.0, 0, 0, 0, 0, 0, 0, 1.0, 0))
    if t >= 4.0 and k % 10 == 5:  # to the fence's edge, for ever, between GPS fixes
        out[4].append(gcs.set_position_target_local_ned_encode(int(t * 1000), 5, 1, M.MAV_FRAME_LOCAL_NED, 0xFF8,
                                                               4.99, 0.0, -3.0, 0, 0, 0, 0, 0, 0, 0, 0))
    if k == 225:
        out[1].append(gcs.command_long_encode(2, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 6, 0, 0, 0, 0, 0))
        out[4].append(gcs.command_long_encode(5, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 6, 0, 0, 0, 0, 0))
    if t < 7.0 and k % 50 == 0:  # a ground station's heartbeat at 1 Hz, then silence
        out[2].append(gcs.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0))
    return out


def _state(fleet: SitlFleet) -> list[tuple]:
    rows = []
    for s in fleet.sitls:
        v, st = s.vehicle, s.model.state
        rows.append((v.mode, st.armed, st.landed, *st.position_ned.tolist(), *v.estimate().tolist(),
                     v.battery.remaining, st.battery_remaining, st.battery_voltage, v.t, s.t,
                     None if v.fix is None else v.fix.time_s, len(v.failsafe_log), v._target is None))
    return rows


@pytest.mark.parametrize("physics", ["kinematic", "pybullet", "pybullet, free flight"])
def test_quiet_ticks_fly_stream_and_fail_safe_as_full_ticks(physics: str) -> None:
    """Both fleets' states are array views (ArrayState, QuadState): quiet ticks write the
    battery arrays, telemetry reads the position arrays. "free flight": the PyBullet fleet's
    vehicles in the air are stepped by the numpy step (free_flight.py) from the first one up."""
    wall = FakeWall()
    kind = physics.split(",")[0]
    (quiet, sent_q), (full, sent_f) = _fleet(True, wall, kind), _fleet(False, wall, kind)
    if physics.endswith("free flight"):
        quiet.world.free_flight_min = full.world.free_flight_min = 1
    assert quiet.quiet.world is quiet.world, "the quiet ticks' array path"
    home_alt = quiet[0].home.alt_m
    flew_free = False
    try:
        for k in range(int(SECONDS / 0.02)):
            wall.now += 0.02  # a wall second per simulated second
            for fleet in (quiet, full):
                for i, msgs in _script(k, home_alt).items():
                    for m in msgs:
                        m.pack(mavlink.MAVLink(None, 255, 190))  # as if it came off the wire
                        fleet[i].vehicle.handle(m)
                        fleet.wake(i)  # what the fleet does for a vehicle it served
                fleet.step()
            assert _state(quiet) == _state(full), f"tick {k}"
            flew_free = flew_free or bool(getattr(quiet.world, "free", np.zeros(1)).any())
    finally:
        quiet.stop()
        full.stop()
    for a, b in zip(quiet.sitls, full.sitls, strict=True):
        assert a.vehicle.failsafe_log == b.vehicle.failsafe_log
        assert a.vehicle.counters.statustext == b.vehicle.counters.statustext
        assert not a.errors and not a.vehicle.counters.handler_errors
    assert sent_q == sent_f, "the same datagrams, byte for byte"
    # what the flight went through: take-off, battery, offboard-loss and data-link-loss failsafes
    logs = [" | ".join(w for _, w in s.vehicle.failsafe_log) for s in quiet.sitls]
    assert "battery low" in logs[0] and "battery critical" in logs[0] and "battery emergency" in logs[0], logs[0]
    assert "offboard setpoints lost" in logs[1] and "offboard lost" in logs[1], logs[1]
    assert "data link lost" in logs[2], logs[2]
    assert not logs[3] and not quiet[3].model.state.armed
    assert quiet[4].vehicle.counters.fence_rejections > 0, "vehicle 4 breached its fence"
    assert all(len(out) > 100 for out in sent_q), "every vehicle streamed"
    ticks = N * int(SECONDS / 0.02)
    assert full.quiet.quiet_ticks == 0 and full.quiet.full_ticks == ticks
    assert quiet.quiet.quiet_ticks > 0.4 * ticks, f"only {quiet.quiet.quiet_ticks} of {ticks} vehicle-ticks were quiet"
    assert np.ptp([s.vehicle.battery.remaining for s in quiet.sitls]) > 0.3
    if physics.endswith("free flight"):
        assert flew_free, "vehicles flew free"
