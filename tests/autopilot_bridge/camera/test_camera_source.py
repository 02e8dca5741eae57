"""The companion's camera sources over real UDP loopback: the MAVLink camera component found
on the vehicle's link and on its own address, frames asked of it (not of the autopilot), one
clear line when no camera answers, and `run --camera` refusing what no source reads."""

from __future__ import annotations

import numpy as np
import pytest
from bridge_pad import free_port
from pymavlink.dialects.v20 import common as mavlink
from typer.testing import CliRunner

from autopilot_bridge.camera import (
    CameraNotFound,
    CameraSpecError,
    FrameSource,
    MavlinkCamera,
    check_spec,
    open_source,
    scheme_of,
)
from autopilot_bridge.link.connection import CommandRejected, VehicleLink
from sim.mavlink import CameraComponent, CameraInfo, Sitl, SitlConfig

CAM = mavlink.MAV_COMP_ID_CAMERA


def _sitl(camera: bool) -> Sitl:
    return Sitl(SitlConfig(instance=34, speedup=8.0, physics="kinematic", camera=camera, gcs_link=False,
                           api_local_port=free_port(), api_remote_port=free_port())).start()


def test_camera_found_on_the_vehicles_link_and_asked_for_frames() -> None:
    sitl = _sitl(camera=True)
    link = VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}")
    try:
        cam = open_source("mavlink", link, link_address="the test's link", timeout_s=5.0)
        assert isinstance(cam, MavlinkCamera) and isinstance(cam, FrameSource) and cam.timed_captures
        t = cam.target
        assert (t.system_id, t.component_id) == (sitl.cfg.sysid, CAM)
        assert (t.vendor, t.model, t.resolution) == ("uavsearch", "sim downward camera", (50, 50))
        assert t.flags & mavlink.CAMERA_CAP_FLAGS_CAPTURE_IMAGE
        link.wait_heartbeat()
        assert link.target == (sitl.cfg.sysid, 1), "the camera's heartbeat is not taken for the vehicle's"
        at = sitl.t + 1.0
        frame, stamp = cam.capture(at, timeout=3.0, tries=3)
        assert frame is not None and frame.shape == (50, 50, 3) and stamp is not None and stamp >= at - 1e-6
        assert sitl.camera is not None and sitl.camera.counters.commands >= 2  # CAMERA_INFORMATION, the ask
        frame2 = cam.request(timeout=3.0, tries=2)
        assert frame2 is not None
        # the autopilot itself serves none (as real PX4), and its ACK is not the camera's
        with pytest.raises(CommandRejected, match="DENIED"):
            link.request_message(mavlink.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE)
        link.request_message(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)  # the autopilot's ACKs still routed
        cam.close()
    finally:
        link.close()
        sitl.stop()


def test_no_camera_is_one_clear_line() -> None:
    sitl = _sitl(camera=False)
    address = f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}"
    link = VehicleLink(address)
    try:
        link.wait_heartbeat()
        with pytest.raises(CameraNotFound) as e:
            open_source("mavlink", link, link_address=address, timeout_s=1.0)
        msg = str(e.value)
        assert msg.startswith(f"no MAVLink camera component answered on {address}") and "is the camera running?" in msg
        assert "--camera" in msg and "\n" not in msg
    finally:
        link.close()
        sitl.stop()


def test_camera_on_its_own_address() -> None:
    """`--camera mavlink:ADDRESS`: the standalone component on a socket of its own, the companion
    listening for it on a second connection."""
    sim_t = [0.0]
    picture = np.full((20, 30, 3), 90, dtype=np.uint8)
    cam_port, companion_port = free_port(), free_port()
    cam = CameraComponent.on_udp(lambda: picture, lambda: sim_t[0], cam_port, companion_port, system_id=3,
                                 info=CameraInfo(width=30, height=20, video_uri="rtsp://127.0.0.1:8554/down")).start()
    vehicle_link = VehicleLink(f"udpin:127.0.0.1:{free_port()}")  # no vehicle there: the camera needs none
    try:
        src = open_source(f"mavlink:udpin:127.0.0.1:{companion_port}", vehicle_link, timeout_s=5.0)
        assert src.link is not vehicle_link and src.own_link
        assert (src.target.system_id, src.target.component_id, src.target.resolution) == (3, CAM, (30, 20))
        assert src.target.flags & mavlink.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
        src.ask(4.0)
        frame, stamp = src.wait(4.0, 0.3)
        assert frame is None, "not before the world's clock gets there"
        sim_t[0] = 4.02
        frame, stamp = src.wait(4.0, 3.0)
        assert frame is not None and np.array_equal(frame, picture) and stamp == 4.02
        src.close()
    finally:
        vehicle_link.close()
        cam.close()


def test_camera_specs() -> None:
    assert scheme_of("mavlink") == ("mavlink", "")
    assert scheme_of("mavlink:udpin:0.0.0.0:14560") == ("mavlink", "udpin:0.0.0.0:14560")
    assert scheme_of("udp://0.0.0.0:5600")[0] == "udp" and scheme_of("rtsp://h/x")[0] == "rtsp"
    assert scheme_of("/dev/video0") == ("device", "/dev/video0") and scheme_of("field.mp4") == ("file", "field.mp4")
    check_spec("mavlink")
    check_spec("mavlink:udpin:0.0.0.0:14560")
    with pytest.raises(CameraSpecError, match="bad MAVLink address"):
        check_spec("mavlink:nowhere")
    with pytest.raises(CameraSpecError, match="no camera source reads"):
        check_spec("gopher://x")


def test_run_refuses_a_camera_no_source_reads() -> None:
    from missions.cli import app

    r = CliRunner().invoke(app, ["run", "--origin-lat", "51.45", "--origin-lon", "-2.58", "--camera", "mavlink:nowhere",
                                 "--connect", f"udpin:127.0.0.1:{free_port()}"])
    assert r.exit_code == 2 and "bad MAVLink address" in " ".join(r.output.replace("│", " ").split())


def test_run_without_a_camera_says_so_and_flies_nothing(tmp_path, monkeypatch) -> None:
    import missions.commands.run as run_cmd
    from missions.cli import app

    monkeypatch.setattr(run_cmd, "CAMERA_TIMEOUT_S", 1.0)
    sitl = _sitl(camera=False)
    try:
        address = f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}"
        r = CliRunner().invoke(app, ["run", "--origin-lat", "51.45", "--origin-lon", "-2.58", "--connect", address,
                                     "--out", str(tmp_path), "--no-tlog"])
        assert r.exit_code == 1, r.output
        assert f"error: no MAVLink camera component answered on {address}" in r.output
        assert not sitl.model.state.armed
    finally:
        sitl.stop()
