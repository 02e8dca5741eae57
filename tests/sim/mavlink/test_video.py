"""The SITL's camera stream (sim/mavlink/video.py): RTP packets stamped with simulated time,
and frames that the companion's VideoSource decodes with their exact capture times. Real UDP
sockets on loopback (ports 27000-27099)."""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from autopilot_bridge.camera.video import VideoSource
from sim.mavlink import Sitl, SitlConfig
from sim.mavlink.video import (
    SEI_UUID,
    VideoConfig,
    VideoStreamer,
    rtp_timestamp,
    sdp_text,
    split_annexb,
)


def _rtp(sock: socket.socket, until: float) -> list[bytes]:
    out = []
    sock.settimeout(0.2)
    while time.monotonic() < until:
        try:
            out.append(sock.recv(65536))
        except TimeoutError:
            if out:
                break
    return out


def test_rtp_timestamps_are_simulated_time_and_each_frame_carries_its_sei() -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 27001))
    st = VideoStreamer(VideoConfig(port=27001, mtu=300), 50, 50)
    try:
        frame = np.zeros((50, 50, 3), np.uint8)
        frame[10:30, 5:45] = (200, 40, 30)
        st.submit(frame, 1.0)
        st.submit(frame, 12.34)
        pkts = _rtp(rx, time.monotonic() + 5)
    finally:
        st.close()
        rx.close()
    stamps = sorted({int.from_bytes(p[4:8], "big") for p in pkts})
    assert stamps == [rtp_timestamp(1.0), rtp_timestamp(12.34)] == [90000, 1110600]
    assert all(p[0] == 0x80 and p[1] & 0x7F == 96 for p in pkts)
    for ts in stamps:
        mine = [p for p in pkts if int.from_bytes(p[4:8], "big") == ts]
        assert [bool(p[1] & 0x80) for p in mine] == [False] * (len(mine) - 1) + [True]  # marker: the frame's end
        seis = [p[12:] for p in mine if p[12] & 0x1F == 6 and SEI_UUID in p]
        body = json.loads(seis[0].split(SEI_UUID)[1][:-1].decode())
        assert body["t"] * 90000 == pytest.approx(ts) and (body["w"], body["h"]) == (50, 50)
    assert any(p[12] & 0x1F == 28 for p in pkts)  # the keyframe did not fit: FU-A fragments


def test_config_and_sdp() -> None:
    with pytest.raises(ValueError, match="video port"):
        VideoConfig(port=70000)
    with pytest.raises(ValueError, match="rate"):
        VideoConfig(port=5600, rate_hz=0)
    with pytest.raises(ValueError, match="host"):
        VideoConfig(port=5600, host="somewhere")
    sdp = sdp_text(VideoConfig(port=5600))
    assert "m=video 5600 RTP/AVP 96" in sdp and "a=rtpmap:96 H264/90000" in sdp and "packetization-mode=1" in sdp
    assert split_annexb(b"\x00\x00\x00\x01\x67\x42\x00\x00\x01\x68\xce") == [b"\x67\x42", b"\x68\xce"]


def test_sitl_stream_decodes_with_exact_capture_times(tmp_path: Path) -> None:
    cfg = SitlConfig(physics="kinematic", camera=True, speedup=5.0, gcs_link=False,
                     api_local_port=27011, api_remote_port=27012, video=VideoConfig(port=27013))
    with Sitl(cfg) as sitl:
        sdp = sitl.video.write_sdp(tmp_path / "camera.sdp")
        with VideoSource("udp://:27013", sdp) as src:
            first = src.wait_frame(0.0, 10.0)
            assert first is not None and first.stamped
            t_at = first.t + 0.55
            f = src.wait_frame(t_at, 10.0)
            time.sleep(0.5)
            got = list(src._ring)
        sent = dict(sitl.video.recent)
    # the first frame at or after t_at: the next 10 Hz lattice point's tick
    assert f is not None and t_at - 1e-3 <= f.t < t_at + 0.1
    assert len(got) >= 5 and sitl.video.frames_dropped == 0
    for g in got:  # every decoded frame: a frame the SITL sent, with its very capture time
        if g.t in sent:
            assert np.abs(g.frame.astype(int) - sent[g.t]).max() <= 1
    assert sum(g.t in sent for g in got) >= 5
    ticks = np.array([g.t for g in got]) / 0.02
    assert np.allclose(ticks, np.round(ticks), atol=1e-6)  # stamped on the SITL's ticks
    lattice = np.array([g.t for g in got]) * 10
    assert np.all(lattice - np.floor(lattice + 1e-6) < 0.2 + 1e-6)  # the first tick at or after k / 10 s
    assert np.all(np.diff([g.t for g in got]) > 0.09)


def test_each_fleet_vehicle_streams_its_own_camera(tmp_path: Path) -> None:
    from sim.mavlink import SitlFleet

    cfgs = [SitlConfig(instance=i, physics="kinematic", camera=True, speedup=5.0, gcs_link=False,
                       api_local_port=27050 + 2 * i, api_remote_port=27051 + 2 * i,
                       video=VideoConfig(port=27060 + 2 * i)) for i in range(2)]
    with SitlFleet(cfgs) as fleet:
        srcs = [VideoSource(f"udp://:{27060 + 2 * i}", fleet[i].video.write_sdp(tmp_path / f"c{i}.sdp"))
                for i in range(2)]
        try:
            firsts = [s.first_frame(10.0) for s in srcs]
        finally:
            for s in srcs:
                s.close()
    assert all(f.stamped and f.t > 0 for f in firsts)


def test_a_lockstep_hold_streams_the_frame_of_its_instant(tmp_path: Path) -> None:
    """A companion-lockstep SITL holds at a capture asked for ahead (here off the stream's
    10 Hz lattice): the frame of that tick goes out on the stream while time stands still."""
    from autopilot_bridge.camera import MavlinkCamera
    from autopilot_bridge.link.connection import VehicleLink

    cfg = SitlConfig(physics="kinematic", camera=True, speedup=5.0, gcs_link=False, companion_lockstep=True,
                     api_local_port=27021, api_remote_port=27022, video=VideoConfig(port=27023))
    link = VehicleLink("udpin:127.0.0.1:27022", tlog=None)
    try:
        with Sitl(cfg) as sitl:
            sdp = sitl.video.write_sdp(tmp_path / "camera.sdp")
            with VideoSource("udp://:27023", sdp) as src:
                link.wait_heartbeat()
                at = round(sitl.t + 1.03, 2)
                MavlinkCamera(link).ask(at)  # the camera component's timed capture
                f = src.wait_frame(at, 10.0)
                held_at = sitl.t
                time.sleep(0.3)
                assert sitl.vehicle.hold_for_companion and sitl.t == held_at  # still held
    finally:
        link.close()
    assert f is not None and at - 1e-3 <= f.t <= at + 0.02 and f.t == pytest.approx(held_at)
