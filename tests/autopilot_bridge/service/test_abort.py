"""bring_down against the real SITL vehicle over MAVLink: each --on-abort choice ends disarmed."""

import socket

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.abort import bring_down
from sim.mavlink import Sitl, SitlConfig


def _port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _vehicle():
    local, remote = _port(), _port()
    sitl = Sitl(SitlConfig(instance=29, speedup=10.0, physics="kinematic", gcs_link=False,
                           api_local_port=local, api_remote_port=remote)).start()
    link = VehicleLink(f"udpin:127.0.0.1:{remote}")
    link.wait_heartbeat()
    link.wait_for(lambda: bool(link.telemetry.home) and link.telemetry.gps.get("fix_type", 0) >= 3, 30, "GPS")
    return sitl, link


def test_hold_leaves_the_operator_time_then_lands_and_disarms() -> None:
    sitl, link = _vehicle()
    try:
        td = bring_down(link, "hold", timeout_s=60, echo=lambda _: None)
        assert td.commanded == [] and td.disarmed, "nothing to do for a disarmed vehicle"
        link.arm()
        td = bring_down(link, "land", timeout_s=60, echo=lambda _: None)
        assert td.commanded == ["disarm"] and td.disarmed, "armed on the ground: disarm it"
        link.arm()
        link.takeoff(link.telemetry.home["alt"] + 3.0)
        link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -2.5, 30, "take-off")
        said: list[str] = []
        td = bring_down(link, "hold", timeout_s=60, hold_s=2.0, echo=said.append)
        assert td.commanded == ["HOLD", "LAND"] and td.disarmed, td
        assert any("nobody landed" in s for s in said)
        link.arm()
        link.takeoff(link.telemetry.home["alt"] + 3.0)
        link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -2.5, 30, "take-off")
        link.land()
        link.wait_for(lambda: link.telemetry.mode == "AUTO.LAND", 5, "LAND mode")
        td = bring_down(link, "rtl", timeout_s=60, echo=said.append)
        assert td.commanded == [] and td.disarmed and "already in AUTO.LAND" in td.note, "no climb-out to RTL"
    finally:
        link.close()
        sitl.stop()
