"""The real autopilots fly our body: arm, take off to 3.5 m, fly 2 m position legs, land and
disarm, with plain pymavlink over each one's own link (sim.bridges.flight_check). Run only
where the binaries are: ARDUPILOT_SITL (arducopter) / PX4_SITL (px4) name them."""

import os

import pytest

from sim.bridges.flight_check import Link, fly
from sim.bridges.world import AutopilotWorld, AutopilotWorldConfig


def _flight(autopilot: str, instance: int, speedup: float, ready_timeout: float, hold_m: float) -> None:
    """hold_m: the estimate's largest distance from a setpoint over a hold's last second (PX4's
    estimate moves with our receiver's 0.6 m noise a fix; measured up to 0.45 m, ArduPilot 0.10)."""
    cfg = AutopilotWorldConfig(autopilot=autopilot, instance=instance, speedup=speedup, camera=False, gcs_port=None)
    with AutopilotWorld(cfg) as world:
        world.wait_physics()
        link = Link(world.companion_address(), lambda: world.t)
        try:
            rep = fly(link, autopilot, truth=lambda: tuple(world.body.state.position_ned), speedup=max(speedup, 5.0),
                      ready_timeout=ready_timeout)
        finally:
            link.close()
        assert world.process is not None and world.process.alive, world.process.tail()
        offset = world.autopilot_clock_s() - world.t
    assert rep.landed_disarmed and rep.takeoff_s is not None and rep.takeoff_s < 10, rep
    for leg in rep.legs:  # each 2 m leg within 0.5 m in a few seconds, and holding near it
        assert leg.settle_s is not None and leg.settle_s < 4.0, rep
        assert leg.hold_err_max_m < hold_m, rep
    # the autopilot's boot clock is the world's clock plus the world's stated offset (PX4 1 s,
    # ArduPilot 0): a message's time_boot_ms is at most that, less its lag in the link
    assert rep.clock["time_boot_minus_world_max_s"] == pytest.approx(offset, abs=0.02), rep.clock


@pytest.mark.skipif(not os.environ.get("PX4_SITL"), reason="PX4_SITL (the px4 SITL binary) is not set")
def test_px4_flies_our_body() -> None:
    _flight("px4", 23, 0.0, ready_timeout=60, hold_m=0.75)


@pytest.mark.skipif(not os.environ.get("ARDUPILOT_SITL"), reason="ARDUPILOT_SITL (the arducopter binary) is not set")
def test_ardupilot_flies_our_body() -> None:
    _flight("ardupilot", 24, 10.0, ready_timeout=60, hold_m=0.3)
