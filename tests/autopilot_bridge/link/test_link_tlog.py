"""The companion's .tlog holds both directions of its link (it used to stay 0 bytes on UDP)."""

import json
import socket
from pathlib import Path

from pymavlink import mavutil

from autopilot_bridge.link.connection import VehicleLink, mavlink
from sim.mavlink import Sitl, SitlConfig


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_companion_tlog_records_what_it_received_and_sent(tmp_path: Path) -> None:
    api_local, api_remote = _free_port(), _free_port()
    cfg = SitlConfig(instance=27, speedup=4.0, physics="kinematic", gcs_link=False,
                     api_local_port=api_local, api_remote_port=api_remote)
    path = tmp_path / "companion.tlog"
    with Sitl(cfg):
        link = VehicleLink(f"udpin:127.0.0.1:{api_remote}", tlog=path, tlog_meta={"what": "test"})
        try:
            link.wait_heartbeat()
            link.request_message(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        finally:
            link.close()
    assert path.stat().st_size > 0 and not path.with_name("companion.tlog.part").exists()
    assert json.loads(path.with_name("companion.tlog.json").read_text())["what"] == "test"
    log = mavutil.mavlink_connection(str(path))
    seen: dict[str, set[int]] = {}
    while (m := log.recv_match()) is not None:
        seen.setdefault(m.get_type(), set()).add(m.get_srcSystem())
    assert cfg.sysid in seen["HEARTBEAT"], "received telemetry is logged"
    assert seen["COMMAND_LONG"] == {245}, "the companion's own commands are logged"
    assert "COMMAND_ACK" in seen
