"""The camera's two paths on loopback, for the same frames: the SITL's RTP/H.264 stream decoded
by the companion's VideoSource, and MAVLink's image protocol (PNG in ENCAPSULATED_DATA, asked
for ahead by capture time) collected by the FrameRequester.

The SITL hovers at 3.5 m and moves between points 4 m apart every 1.5 s (frames of grass, cattle
and the field's edge at 10 Hz of simulated time), at real time: per frame, the decode time (packet -> RGB at the camera's size; PNG -> RGB), the
end-to-end latency (the SITL's capture on the wall clock -> the frame in the companion's
hands), the frame's cost on the simulation's thread (render + queue) and on the encoder's, and
the SITL's real-time factor at speed-ups with the stream on and off.

    PYTHONPATH=. python benchmarks/bench_video.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from autopilot_bridge.camera import FrameRequester, decode_png_stamped
from autopilot_bridge.camera.video import VideoSource
from autopilot_bridge.link.connection import VehicleLink
from sim.mavlink import Sitl, SitlConfig
from sim.mavlink.images import encode_png
from sim.mavlink.video import VideoConfig

BASE_PORT = 27900


class TimedSitl(Sitl):
    """The SITL, its video frame's cost on the simulation's thread measured, and the wall time
    of each tick (the MAVLink frame of a tick is captured on it)."""

    def __init__(self, cfg: SitlConfig) -> None:
        super().__init__(cfg)
        self.stream_s: list[float] = []
        self.tick_wall: dict[float, float] = {}

    def step(self) -> None:
        w = time.time()
        super().step()
        self.tick_wall[round(self.t, 6)] = w

    def _stream_video(self) -> None:
        t0 = time.perf_counter()
        due = self.video is not None and self.video.due(self.t)
        super()._stream_video()
        if due:
            self.stream_s.append(time.perf_counter() - t0)


def fly(link: VehicleLink, stop: threading.Event) -> None:
    """Take off to 3.5 m and go round four points 4 m apart (OFFBOARD setpoints on a thread)."""
    link.wait_for(lambda: bool(link.telemetry.home) and link.telemetry.gps.get("fix_type", 0) >= 3, 30, "GPS")
    link.arm()
    link.takeoff(link.telemetry.home["alt"] + 3.5)
    link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -3.0, 30, "take-off")
    points = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]

    def setpoints() -> None:
        k, t_next = 0, 0.0
        while not stop.is_set():
            if time.monotonic() > t_next:
                k, t_next = k + 1, time.monotonic() + 1.5
            link.set_position_ned(*points[k % 4], -3.5)
            time.sleep(0.05)

    threading.Thread(target=setpoints, daemon=True).start()
    time.sleep(0.2)
    link.set_mode("OFFBOARD")


def pct(x, q=(50, 99)) -> str:
    if not len(x):
        return "n/a"
    a = np.percentile(np.asarray(x, float) * 1e3, q)
    return " / ".join(f"{v:6.2f}" for v in a)


def latency(seconds: float) -> None:
    cfg = SitlConfig(physics="pybullet", speedup=1.0, gcs_link=False, api_local_port=BASE_PORT,
                     api_remote_port=BASE_PORT + 1, video=VideoConfig(port=BASE_PORT + 2))
    link = VehicleLink(f"udpin:0.0.0.0:{BASE_PORT + 1}", tlog=None)
    sitl = TimedSitl(cfg).start()
    sdp = sitl.video.write_sdp(Path(tempfile.mkdtemp()) / "camera.sdp")
    src = VideoSource(f"udp://:{BASE_PORT + 2}", sdp, ring=100000)
    req = FrameRequester(link)
    stop = threading.Event()
    mav: dict[float, float] = {}  # asked capture time -> arrival wall time
    mav_t: dict[float, float] = {}  # asked capture time -> the frame's stamp
    try:
        link.wait_heartbeat()
        src.first_frame(10.0)
        errors_before = src.errors  # the frames before the first keyframe do not decode
        fly(link, stop)
        t_start = sitl.t + 1.0
        asks = [round(t_start + 0.5 * k, 6) for k in range(int(seconds * 2))]  # on the 10 Hz lattice

        def mavlink_path() -> None:
            for t in asks:
                # asked a little early: COMMAND_LONG carries the time as float32 (8.1 -> 8.1000004,
                # captured a tick later, at 8.12), and the frame should be the video's of that tick
                req.ask(t - 0.005)
                frame, stamp = req.wait(t - 0.005, 5.0)
                if frame is not None:
                    mav[t], mav_t[t] = time.time(), stamp

        th = threading.Thread(target=mavlink_path)
        th.start()
        th.join(seconds + 15)
        time.sleep(0.3)
        ring = list(src._ring)
        frames = list(sitl.video.recent)
    finally:
        stop.set()
        src.close()
        link.close()
        sitl.stop()
    # the whole stream
    dec = [f.decode_s for f in ring]
    e2e = [f.arrived_wall - f.sent_wall for f in ring if f.sent_wall is not None]
    # the same frames on both paths: the video frame of the tick a MAVLink capture was asked for
    by_t = {round(f.t, 6): f for f in ring}
    pairs = []
    for t, arrived in mav.items():
        stamp = round(mav_t[t], 6)
        v = by_t.get(stamp) or next((f for f in ring if abs(f.t - mav_t[t]) < 1e-3), None)
        cap = sitl.tick_wall.get(stamp)
        if v is not None and cap is not None:
            pairs.append((v.arrived_wall - cap, arrived - cap))

    png = [encode_png(f, t) for t, f in frames[-20:]]
    png_dec = []
    for data in png:
        t0 = time.perf_counter()
        decode_png_stamped(data)
        png_dec.append(time.perf_counter() - t0)
    print(f"{seconds:g} s at real time, 10 Hz, {sitl.video.out_w} x {sitl.video.out_h} H.264 "
          f"(qp {cfg.video.qp}, {sitl.video.bytes_sent / max(sitl.video.frames_sent, 1):.0f} B/frame) "
          f"vs 50 x 50 PNG over MAVLink ({np.mean([len(p) for p in png]):.0f} B/frame)")
    print(f"  frames: {sitl.video.frames_sent} streamed, {sitl.video.frames_dropped} dropped by the encoder, "
          f"{src.decoded} decoded, {src.errors - errors_before} decode errors after the first frame "
          f"({errors_before} before it); MAVLink {len(mav)} of {len(asks)} captures")
    print("                                      p50 / p99 (ms)")
    print(f"  video decode (packet -> RGB)      {pct(dec)}")
    print(f"  PNG decode (bytes -> RGB)         {pct(png_dec)}")
    print(f"  video end-to-end (capture->RGB)   {pct(e2e)}")
    if pairs:
        p = np.array(pairs)
        print(f"  same {len(p)} frames, tick -> companion: video {pct(p[:, 0])}, MAVLink {pct(p[:, 1])}; "
              f"MAVLink / video p50 {np.median(p[:, 1]) / np.median(p[:, 0]):.1f}x")
    print(f"  SITL thread per video frame (render + queue) {pct(sitl.stream_s)}; "
          f"encoder thread (encode + packetise + send) {pct(sitl.video.encode_s)}")


def real_time_factor(speedup: float, video: bool, seconds: float = 3.0) -> tuple[float, tuple[int, int]]:
    port = BASE_PORT + 10 + int(video)
    cfg = SitlConfig(physics="pybullet", speedup=speedup, gcs_link=False, api_local_port=BASE_PORT + 20,
                     api_remote_port=BASE_PORT + 21, video=VideoConfig(port=port) if video else VideoConfig())
    sitl = Sitl(cfg)
    w0 = time.monotonic()
    sitl.start()
    time.sleep(seconds)
    factor = sitl.t / (time.monotonic() - w0)
    dropped = (sitl.video.frames_dropped, sitl.video.frames_skipped) if sitl.video else (0, 0)
    sitl.stop()
    return factor, dropped


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=20.0)
    args = ap.parse_args()
    latency(args.seconds)
    print("  SITL real-time factor (video off / on; frames the encoder dropped, lattice frames skipped "
          "past max_wall_hz):")
    for s in (1.0, 5.0, 20.0, 0.0):
        off, _ = real_time_factor(s, False)
        on, dropped = real_time_factor(s, True)
        print(f"    speedup {s:4g}{' (max)' if s == 0 else '      '}: {off:6.1f}x / {on:6.1f}x  "
              f"({dropped[0]} dropped, {dropped[1]} skipped)")


if __name__ == "__main__":
    main()
