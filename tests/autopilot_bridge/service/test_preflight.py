"""The pre-flight failsafe check on a real vehicle's link (our SITL in its PX4 dialect)."""

from __future__ import annotations

import math
import socket

import pytest

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.preflight import UnsafeFailsafe, ensure_failsafe, read_failsafe
from sim.mavlink import Sitl, SitlConfig


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_preflight_refuses_and_sets_on_a_real_link() -> None:
    sitl = Sitl(SitlConfig(instance=0, speedup=4.0, physics="kinematic", camera=False, gcs_link=False,
                           api_local_port=_free_port(), api_remote_port=_free_port())).start()
    try:
        with VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}") as link:
            link.wait_heartbeat()
            assert all(r.ok for r in read_failsafe(link, 245))
            assert ensure_failsafe(link, 245) == []
            assert link.set_param("COM_OBL_RC_ACT", 5) == 5
            with pytest.raises(UnsafeFailsafe, match=r"COM_OBL_RC_ACT = 5: .*a safe value: 3.*--set-failsafe"):
                ensure_failsafe(link, 245)
            assert ensure_failsafe(link, 245, set_safe=True) == ["--set-failsafe: COM_OBL_RC_ACT 5 -> 3"]
            assert link.get_param("COM_OBL_RC_ACT") == 3
            assert link.get_param("NO_SUCH_PARAM", timeout=0.2, retries=2) is None
            assert math.isclose(link.get_param("COM_OF_LOSS_T"), 1.0)
    finally:
        sitl.stop()
