"""The fleet's vectorised telemetry (sim/mavlink/fleet_telemetry.py) packs the bytes each
vehicle's own builder packs (telemetry.py through wire.ENCODER), on states drawn at random:
rounding to 1e-7 degrees, truncation to cm and mm, float32, headings, modes, health bits and
vehicles without a GPS fix included."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sim.mavlink import wire
from sim.mavlink.fleet_telemetry import VECTORISED, Gathered, row_dtype
from sim.mavlink.telemetry import BUILDERS, Snapshot
from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsFix
from sim.vehicle.model import VehicleState

MODES = ["AUTO.LOITER", "AUTO.TAKEOFF", "OFFBOARD", "POSCTL", "AUTO.MISSION", "AUTO.RTL", "AUTO.LAND"]


def _vehicles(k: int, seed: int) -> list[SimpleNamespace]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        home = HomePosition(float(rng.uniform(-60, 60)), float(rng.uniform(-179, 179)), float(rng.uniform(-10, 500)))
        s = VehicleState(time_s=0.0, position_ned=rng.normal(0, 300, 3), velocity_ned=rng.normal(0, 4, 3),
                         attitude_rpy=rng.uniform(-np.pi, np.pi, 3), body_rates=rng.normal(0, 2, 3),
                         armed=bool(rng.integers(2)), landed=bool(rng.integers(2)),
                         battery_voltage=float(rng.uniform(14, 16.8)), battery_remaining=float(rng.uniform(0, 1)))
        fix = None if rng.random() < 0.2 else GpsFix(float(rng.uniform(0, 5000)), float(rng.uniform(-60, 60)),
                                                     float(rng.uniform(-179, 179)), float(rng.uniform(-10, 500)),
                                                     rng.normal(0, 4, 3), float(rng.uniform(0.5, 3)),
                                                     float(rng.uniform(0.5, 3)), 3, 12)
        out.append(SimpleNamespace(t=float(rng.uniform(0, 5000)), model=SimpleNamespace(state=s), home=home,
                                   gps=SimpleNamespace(estimate_error=rng.normal(0, 1, 3)), fix=fix,
                                   mode=str(rng.choice(MODES)), _fence_hold=bool(rng.random() < 0.2),
                                   failures=set() if rng.random() < 0.8 else {"battery"},
                                   fences=SimpleNamespace(breached=False)))  # no polygon fence
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_vectorised_payloads_are_the_builders_bytes(seed: int) -> None:
    vs = _vehicles(400, seed)
    x = Gathered(vs)
    for mid, build in VECTORISED.items():
        got = build(x)
        for v, p in zip(vs, got, strict=True):
            s = v.model.state
            snap = Snapshot(v.t, s, s.position_ned + v.gps.estimate_error, v.home, v.fix, v.mode, 1,
                            fence_breached=v._fence_hold, battery_ok="battery" not in v.failures)
            assert p == BUILDERS[mid](wire.ENCODER, snap), (mid, v)


def test_record_dtypes_match_the_message_structs() -> None:
    from pymavlink.dialects.v20 import common as mavlink

    for cls in (mavlink.MAVLink_battery_status_message, mavlink.MAVLink_statustext_message,
                mavlink.MAVLink_gps_raw_int_message, mavlink.MAVLink_global_position_int_message):
        assert row_dtype(cls).itemsize == cls.unpacker.size
