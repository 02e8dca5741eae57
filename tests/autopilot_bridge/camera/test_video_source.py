"""The companion's video camera source (autopilot_bridge/camera/video.py): the detector finds
on decoded frames what it finds on the MAVLink path's PNGs; frames are found by capture time;
a bad URL or a missing SDP is one clear error naming it. Real UDP on loopback (27100-27199)."""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from autopilot_bridge.camera import decode_png_stamped
from autopilot_bridge.camera.video import VideoSource, VideoSourceError, yuv420_to_rgb
from autopilot_bridge.detection.detector import find_blobs
from sim.mavlink.images import encode_png
from sim.mavlink.video import VideoConfig, VideoStreamer, to_yuv420
from sim.vehicle import ViewRenderer, WorldState


class Feed:
    """Streams frames at 10 Hz of its own clock (t = 0.1 k) on a thread until stopped."""

    def __init__(self, st: VideoStreamer, frames: list[np.ndarray], t0: float = 0.0) -> None:
        self.st, self.frames, self.t = st, frames, t0
        self.stop = threading.Event()
        self.sent: dict[float, np.ndarray] = {}
        self.th = threading.Thread(target=self._run, daemon=True)
        self.th.start()

    def _run(self) -> None:
        k = 0
        while not self.stop.is_set():
            f = self.frames[k % len(self.frames)]
            self.sent[round(self.t, 6)] = f
            self.st.submit(f, round(self.t, 6))
            self.t += 0.1
            k += 1
            time.sleep(0.02)

    def close(self) -> None:
        self.stop.set()
        self.th.join()
        self.st.close()


def _blobs(frame: np.ndarray) -> list[tuple[float, float, int]]:
    return sorted((round(b.row, 3), round(b.col, 3), b.pixels) for b in find_blobs(frame))


def test_colour_conversion_round_trip_is_within_a_level() -> None:
    rgb = np.random.default_rng(0).integers(0, 256, (50, 50, 3), dtype=np.uint8)
    for scale in (2, 4):
        back = yuv420_to_rgb(to_yuv420(rgb, scale), 50, 50)
        assert np.abs(back.astype(int) - rgb).max() <= 2


def test_cows_found_on_decoded_frames_as_on_the_pngs(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    r = ViewRenderer(10, 10, 5, image=50, seed=3)
    try:
        views = []
        while len(views) < 12:  # views with a cow in them
            tg = rng.uniform(0, 9, (5, 2))
            v = r.render_view(WorldState(10, 10, tg), tg[rng.integers(5)] + rng.uniform(-1, 1, 2))
            if find_blobs(v):
                views.append(v)
    finally:
        r.close()
    st = VideoStreamer(VideoConfig(port=27101), 50, 50)
    sdp = st.write_sdp(tmp_path / "camera.sdp")
    feed = Feed(st, views)
    try:
        with VideoSource("udp://:27101", sdp) as src:
            src.wait_frame(feed.t + 2.5, 10.0)  # a full round of views after the first keyframe
            got = list(src._ring)
    finally:
        feed.close()
    checked = 0
    for g in got:
        sent = feed.sent.get(round(g.t, 6))
        assert sent is not None, f"decoded a frame stamped {g.t}, never sent"
        png, t_png = decode_png_stamped(encode_png(sent, g.t))  # the MAVLink path's frame
        assert t_png == pytest.approx(g.t, abs=1e-6)
        assert _blobs(g.frame) == _blobs(png) and _blobs(png), f"frame at {g.t}"
        checked += 1
    assert checked >= 12


def test_wait_finds_the_frame_of_its_instant_and_times_out(tmp_path: Path) -> None:
    frames = [np.full((50, 50, 3), (k * 20, 255 - k * 20, 90), np.uint8) for k in range(10)]
    st = VideoStreamer(VideoConfig(port=27102), 50, 50)
    sdp = st.write_sdp(tmp_path / "camera.sdp")
    feed = Feed(st, frames, t0=100.0)
    try:
        with VideoSource("udp://:27102", sdp) as src:
            first = src.wait_frame(0.0, 10.0)
            frame, t = src.wait(first.t + 0.35, 5.0)
            assert t == pytest.approx(first.t + 0.4, abs=1e-6)  # the first at or after: 0.4 later
            assert np.abs(frame.astype(int) - feed.sent[round(t, 6)]).max() <= 1
            again, t2 = src.capture(first.t + 0.35, timeout=1.0, tries=1)  # already in the ring
            assert t2 == t and np.array_equal(again, frame)
            assert src.request(1.0, 2) is not None
            src.ask(1e9)  # nothing to ask of a stream
            assert src.timed_captures is False
            t0 = time.monotonic()
            assert src.wait(1e9, 0.3) == (None, None)
            assert time.monotonic() - t0 < 1.0
    finally:
        feed.close()


def test_bad_urls_and_missing_sdp_are_one_clear_error(tmp_path: Path) -> None:
    with pytest.raises(VideoSourceError, match=r"udp://:27103: an RTP stream needs its SDP file"):
        VideoSource("udp://:27103")
    missing = tmp_path / "nope.sdp"
    with pytest.raises(VideoSourceError, match=rf"udp://:27103: its SDP file {missing} cannot be read"):
        VideoSource("udp://:27103", missing)
    (tmp_path / "bad.sdp").write_text("v=0\n")
    with pytest.raises(VideoSourceError, match="not an SDP file with a video stream"):
        VideoSource("udp://:27103", tmp_path / "bad.sdp")
    with pytest.raises(VideoSourceError, match=rf"camera {tmp_path / 'none.mp4'}: no such file"):
        VideoSource(str(tmp_path / "none.mp4"))
    with pytest.raises(VideoSourceError, match="/dev/video97: no such V4L2 device"):
        VideoSource("/dev/video97")
    st = VideoStreamer(VideoConfig(port=27104), 50, 50)  # an SDP, but nothing streams to its port
    sdp = st.write_sdp(tmp_path / "camera.sdp")
    st.close()
    t0 = time.monotonic()
    with VideoSource("udp://:27104", sdp) as src:  # RTP opens on its SDP alone
        with pytest.raises(VideoSourceError, match=r"udp://:27104: no frame decoded within 0.5 s"):
            src.first_frame(0.5)
    assert time.monotonic() - t0 < 5.0
    with VideoSource("rtsp://127.0.0.1:27105/camera") as src:  # nobody serves RTSP there
        with pytest.raises(VideoSourceError, match=r"camera rtsp://127.0.0.1:27105/camera: cannot read the stream"):
            src.first_frame(5.0)


def test_frames_damaged_by_lost_packets_are_left_out(tmp_path: Path) -> None:
    """A forwarder drops every 12th RTP packet: each frame VideoSource keeps is the one sent at
    its time (the SITL's CRC of the lossless frame; FFmpeg conceals the damage silently)."""
    frames = []
    for k in range(7):  # grass and a cow that walks
        f = np.full((50, 50, 3), (70, 140, 60), np.uint8)
        f[10 + 4 * k:22 + 4 * k, 5 + 5 * k:13 + 5 * k] = (120, 70, 40)
        frames.append(f)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 27110))
    rx.settimeout(0.1)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    stop = threading.Event()

    def forward() -> None:
        k = 0
        while not stop.is_set():
            try:
                data = rx.recv(65536)
            except TimeoutError:
                continue
            k += 1
            if k % 12:
                tx.sendto(data, ("127.0.0.1", 27111))

    fwd = threading.Thread(target=forward, daemon=True)
    fwd.start()
    st = VideoStreamer(VideoConfig(port=27110, mtu=200), 50, 50)
    sdp = tmp_path / "camera.sdp"
    sdp.write_text(st.sdp().replace("m=video 27110", "m=video 27111"))
    feed = Feed(st, frames)
    try:
        with VideoSource("udp://:27111", sdp) as src:
            first = src.first_frame(10.0)
            src.wait_frame(first.t + 3.0, 10.0)
            got = list(src._ring)
            left_out = src.corrupt + src.unstamped
    finally:
        feed.close()
        stop.set()
        fwd.join()
        rx.close()
        tx.close()
    assert len(got) >= 5 and left_out >= 3
    for g in got:
        assert np.abs(g.frame.astype(int) - feed.sent[round(g.t, 6)]).max() <= 1, f"frame at {g.t}"


def test_a_restarted_stream_empties_the_ring(tmp_path: Path) -> None:
    """A new SITL on the same port starts its clock at 0 again: the old flight's frames must not
    answer the new flight's wait(t)."""
    frame = np.full((50, 50, 3), (70, 140, 60), np.uint8)
    sdp = tmp_path / "camera.sdp"
    st = VideoStreamer(VideoConfig(port=27120), 50, 50)
    st.write_sdp(sdp)
    with VideoSource("udp://:27120", sdp) as src:
        for k in range(25):
            st.submit(frame, 10.0 + 0.1 * k)
            time.sleep(0.02)
        assert src.wait_frame(12.0, 5.0) is not None
        st.close()
        st = VideoStreamer(VideoConfig(port=27120), 50, 50)
        for k in range(15):
            st.submit(frame, 0.1 * k)
            time.sleep(0.02)
        f = src.wait_frame(0.5, 5.0)
        st.close()
        assert f is not None and f.t == pytest.approx(0.5) and src.restarts == 1
        assert all(g.t < 2.0 for g in src._ring)


def test_a_video_file_plays_at_its_pace_stamped_on_the_clock(tmp_path: Path) -> None:
    import av

    path = tmp_path / "clip.mp4"
    with av.open(str(path), "w") as out:
        s = out.add_stream("libx264", rate=20)
        s.width, s.height, s.pix_fmt = 64, 48, "yuv420p"
        for k in range(10):  # half a second
            rgb = np.full((48, 64, 3), (10 * k, 120, 60), np.uint8)
            for p in s.encode(av.VideoFrame.from_ndarray(rgb, format="rgb24")):
                out.mux(p)
        for p in s.encode():
            out.mux(p)
    clock = [100.0]
    t0 = time.monotonic()
    with VideoSource(str(path), clock=lambda: clock[0]) as src:
        first = src.first_frame(5.0)
        assert not first.stamped and first.t == 100.0 and first.frame.shape == (48, 64, 3)
        assert src.request(2.0, 1) is not None  # a later frame comes
        while not src.ended and time.monotonic() - t0 < 5:
            time.sleep(0.05)
    assert src.decoded == 10 and time.monotonic() - t0 >= 0.4  # not all at once
