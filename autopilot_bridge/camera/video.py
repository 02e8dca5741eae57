"""A camera source that decodes a video stream, as a companion computer takes a real drone's
camera: RTP/H.264 on UDP (PX4 Gazebo's and our SITL's port 5600, described by an SDP file),
RTSP, a V4L2 device (/dev/videoN) or a video file (played at its own pace): anything PyAV
(FFmpeg) opens.

Frames are decoded on a thread of their own and kept, stamped, in a short ring buffer, so a
decision that wants the picture of simulated time t finds it however the stream and the
decision loop drift (`wait(t)`: the first frame captured at or after t). The stamp is the
capture time the stream carries: our SITL puts each frame's simulated capture time in a
user-data-unregistered SEI (UUID SEI_UUID, a JSON body {"t": ..., "w", "h": the camera's own
size, a CRC of the lossless frame; sim/mavlink/video.py), which FFmpeg hands over as frame
side data. A stream without it (a real camera) is stamped on arrival, on the `clock` the
companion asks in. Frames damaged by lost packets (the CRC does not match, or FFmpeg flags them)
and frames of a stamped stream whose stamp was lost are left out, counted: a decision waits for
the next whole one rather than decide on a wrong picture or a wrong time.

Our SITL scales its 50 px frames up by an integer factor so H.264's 4:2:0 chroma keeps every
camera pixel's colour; the SEI names the camera's size and each block is averaged back and
converted to RGB exactly (yuv420_to_rgb), so the detector sees the frame it would have seen
over MAVLink within a level or two of colour.

Same methods as the MAVLink FrameRequester (autopilot_bridge/camera/mavlink_camera.py); a stream cannot be
asked for a capture at an instant, so `ask` does nothing and `timed_captures` is False (the
take-off then flies on command timing: Pilot._ask_ahead).
"""

from __future__ import annotations

import json
import logging
import os
import re
import tempfile
import threading
import time
import zlib
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from .source import ask_until_whole

log = logging.getLogger(__name__)

#: the SITL's time-stamp SEI (a wire format shared with sim/mavlink/video.py, not an import:
#: the companion sees the camera only through the stream)
SEI_UUID = bytes.fromhex("75617673656172636874696d65763031")
RING_FRAMES = 64  # 6.4 s of stream at 10 Hz
OPEN_RETRY_S = 1.0  # an open that hears nothing this long is tried again (and close() seen)
READ_TIMEOUT_S = 0.5  # a read blocked this long returns, so close() is quick; the stream is then read on
TOLERANCE_S = 1e-3  # a frame stamped this much before the asked instant is its frame (float sums)


class VideoSourceError(RuntimeError):
    """The stream cannot be opened or has no description; the message names it."""


@dataclass(frozen=True)
class StampedFrame:
    t: float  # capture time (simulated, from the stream; else arrival on the source's clock)
    frame: np.ndarray  # (H, W, 3) uint8 RGB at the camera's own size
    index: int  # decoded frames before this one
    arrived_wall: float  # time.time() when it was decoded
    sent_wall: float | None  # the sender's time.time() at capture (SITL streams only): end-to-end latency
    decode_s: float  # wall seconds of decoding and converting this frame
    stamped: bool  # t came from the stream


@dataclass(frozen=True)
class _Input:
    target: str  # what av.open gets
    format: str | None
    options: dict[str, str]
    temp: Path | None = None  # a rewritten SDP, removed on close
    live: bool = True  # False: a file, played at its own pace (its frames' times) rather than as fast as it decodes


def describe(url: str, sdp: str | os.PathLike | None = None) -> _Input:
    """Where and how to open `url`. udp://[HOST]:PORT and rtp://... need the stream's SDP (RTP
    carries no codec description): `sdp` is its path; the URL's port (and host, where given)
    replace the SDP's, so `udp://:5602` with one SDP file listens on 5602."""
    low = {"fflags": "nobuffer", "flags": "low_delay"}
    parts = urlsplit(url)
    if parts.scheme in ("udp", "rtp"):
        if sdp is None:
            raise VideoSourceError(f"camera {url}: an RTP stream needs its SDP file (uavsearch sitl writes it "
                                   "next to the field file and names it there: run --field FILE, or --video-sdp PATH)")
        path = Path(sdp)
        try:
            text = path.read_text()
        except OSError as e:
            raise VideoSourceError(f"camera {url}: its SDP file {path} cannot be read ({e.strerror or e})") from e
        if not re.search(r"^m=video ", text, re.M):
            raise VideoSourceError(f"camera {url}: {path} is not an SDP file with a video stream (no m=video line)")
        try:
            port = parts.port
        except ValueError as e:
            raise VideoSourceError(f"camera {url}: bad port ({e})") from e
        if port is not None:
            text = re.sub(r"^m=video \d+", f"m=video {port}", text, flags=re.M)
        if parts.hostname:
            text = re.sub(r"^c=IN IP4 \S+", f"c=IN IP4 {parts.hostname}", text, flags=re.M)
        fd, tmp = tempfile.mkstemp(prefix="uavsearch-camera-", suffix=".sdp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        return _Input(tmp, "sdp", {**low, "protocol_whitelist": "file,udp,rtp", "reorder_queue_size": "0",
                                   "probesize": "32", "analyzeduration": "0"}, Path(tmp))
    if url.endswith(".sdp"):
        if not Path(url).is_file():
            raise VideoSourceError(f"camera {url}: no such SDP file")
        return _Input(url, "sdp", {**low, "protocol_whitelist": "file,udp,rtp", "reorder_queue_size": "0",
                                   "probesize": "32", "analyzeduration": "0"})
    if url.startswith("/dev/video"):
        if not Path(url).exists():
            raise VideoSourceError(f"camera {url}: no such V4L2 device")
        return _Input(url, "v4l2", {})
    if parts.scheme in ("rtsp", "rtsps"):
        return _Input(url, None, {**low, "rtsp_transport": "udp"})
    if parts.scheme in ("", "file") and not Path(parts.path if parts.scheme else url).exists():
        raise VideoSourceError(f"camera {url}: no such file (give a video file, /dev/videoN, rtsp://... or "
                               "udp://:PORT with its SDP)")
    return _Input(url, None, {}, live=parts.scheme not in ("", "file"))


def read_sei_stamp(data: bytes) -> dict | None:
    """The body of our time-stamp SEI (side data: UUID + JSON), None when it is another's."""
    if len(data) < 17 or data[:16] != SEI_UUID:
        return None
    try:
        body = json.loads(bytes(data[16:]).decode("ascii"))
    except (UnicodeDecodeError, ValueError):
        return None
    return body if isinstance(body, dict) and isinstance(body.get("t"), int | float) else None


def _block_mean(p: np.ndarray, height: int, width: int) -> np.ndarray:
    h, w = p.shape
    return p.reshape(height, h // height, width, w // width).astype(np.float32).mean(axis=(1, 3))


def yuv420_to_rgb(yuv: np.ndarray, width: int, height: int) -> np.ndarray | None:
    """The (H * 3 / 2, W) BT.601 limited-range 4:2:0 planes of a frame scaled up by an integer
    factor -> the camera's (height, width, 3) RGB: each block's luma and chroma averaged, then
    converted in floating point (the inverse of the SITL's to_yuv420; swscale's integer
    conversion with interpolated chroma moved a cow's outline by up to 15 levels). None when
    the frame is not an integer multiple of that size."""
    h, w = yuv.shape[0] * 2 // 3, yuv.shape[1]
    if width <= 0 or height <= 0 or w % width or h % height or (h // height) % 2 and h != height:
        return None
    y = yuv[:h]
    u = yuv[h:h + h // 4].reshape(h // 2, w // 2)
    v = yuv[h + h // 4:].reshape(h // 2, w // 2)
    if h == height:  # not scaled up: one chroma sample per 2 x 2 camera pixels
        u = np.repeat(np.repeat(u, 2, axis=0), 2, axis=1)
        v = np.repeat(np.repeat(v, 2, axis=0), 2, axis=1)
    yf = _block_mean(y, height, width) - 16.0
    uf = _block_mean(u, height, width) - 128.0
    vf = _block_mean(v, height, width) - 128.0
    k = 255.0 / 219.0
    c = 255.0 / 224.0
    r = k * yf + c * 1.402 * vf
    g = k * yf - c * (1.772 * 0.114 / 0.587) * uf - c * (1.402 * 0.299 / 0.587) * vf
    b = k * yf + c * 1.772 * uf
    return np.clip(np.rint(np.stack([r, g, b], axis=-1)), 0, 255).astype(np.uint8)


class VideoSource:
    """Decodes a video stream on a thread; frames are found by their capture time. Raises
    VideoSourceError (naming the URL) when the stream cannot be opened within open_timeout."""

    timed_captures = False

    def __init__(self, url: str, sdp: str | os.PathLike | None = None,
                 clock: Callable[[], float] = time.monotonic, ring: int = RING_FRAMES,
                 asker: Callable[[float], None] | None = None) -> None:
        """clock: the time scale of `wait(at_s)` for frames the stream does not stamp (in a
        flight: the simulated time telemetry carries); stamped frames use the stream's.
        asker: asks the vehicle for a capture at a simulated instant (over MAVLink: what holds a
        companion-lockstep SITL there, which then streams that instant's frame too); with one,
        ask() calls it and timed_captures is True, so a video flight is flown on the simulated
        clock as a MAVLink-camera one. Only a simulation has that; a real stream has none.
        What is wrong with the URL or SDP raises here; the stream is opened on the decoding
        thread (FFmpeg's open of an RTP stream waits for its first packets): first_frame()
        raises what went wrong there."""
        self.url, self.clock, self.asker = url, clock, asker
        self.timed_captures = asker is not None
        self._in = describe(url, sdp)
        self._ring: deque[StampedFrame] = deque(maxlen=ring)
        self._cv = threading.Condition()
        self._stop = threading.Event()
        self.container = None
        self.error: VideoSourceError | None = None  # why the stream could not be opened or read
        self.decoded = 0
        self.errors = 0  # packets that did not decode
        self.corrupt = 0  # frames damaged by losses (FFmpeg's flag, or the SITL's CRC), left out
        self.unstamped = 0  # frames of a stamping stream whose stamp was lost, left out
        self.restarts = 0  # the stream's clock ran backwards (a new SITL): the ring was emptied
        self._stamps_seen = False
        self.requests = 0
        self.ended = False  # a file played to its end, or the stream broke
        self._thread = threading.Thread(target=self._run, name="video-source", daemon=True)
        self._thread.start()

    # -- decoding -----------------------------------------------------------------------
    def _open(self):
        """The container, opened with short timeouts so close() is never held up for long;
        None when stopped first."""
        import av

        while not self._stop.is_set():
            try:
                return av.open(self._in.target, format=self._in.format, options=self._in.options,
                               timeout=(OPEN_RETRY_S, READ_TIMEOUT_S))
            except (TimeoutError, av.error.ExitError):  # nothing yet (an RTSP server or a device coming up)
                continue
        return None

    def _run(self) -> None:
        try:
            container = self._open()
            if container is None:
                return
            self.container = container
            if not container.streams.video:
                raise VideoSourceError(f"camera {self.url}: no video stream in it")
            stream = container.streams.video[0]
            stream.thread_type = "SLICE"  # frame threading would hold frames back
            self._decode_loop(container, stream)
        except VideoSourceError as e:
            self.error = e
        except Exception as e:  # FFmpeg's errors name what failed: no such host, refused, bad data
            if not self._stop.is_set():
                self.error = VideoSourceError(f"camera {self.url}: cannot read the stream ({e})")
                log.warning("%s", self.error)
        finally:
            with self._cv:
                self.ended = True
                self._cv.notify_all()

    def _decode_loop(self, container, stream) -> None:
        import av

        start: tuple[float, float] | None = None  # a file's (first frame's time, wall clock then)
        while not self._stop.is_set():
            try:
                for packet in container.demux(stream):
                    if self._stop.is_set():
                        return
                    t0 = time.perf_counter()
                    for frame in packet.decode():
                        if not self._in.live and frame.time is not None:  # a file: at its own pace
                            start = start or (frame.time, time.monotonic())
                            lag = start[1] + frame.time - start[0] - time.monotonic()
                            if lag > 0 and self._stop.wait(lag):
                                return
                            t0 = time.perf_counter()
                        self._keep(frame, t0)
                else:
                    return  # end of file
            except (TimeoutError, av.error.ExitError):  # nothing came for READ_TIMEOUT_S: read on
                continue
            except av.error.InvalidDataError:  # a lost packet broke a frame: the next keyframe mends it
                self.errors += 1

    def _keep(self, frame, t0: float) -> None:
        if frame.is_corrupt:  # concealed loss (a packet missing here or in a reference): not a picture to decide on
            self.corrupt += 1
            return
        body = None
        for sd in frame.side_data:
            if "SEI_UNREGISTERED" in str(sd.type):
                body = read_sei_stamp(bytes(sd)) or body
        if body is None and self._stamps_seen:  # its stamp was lost on the way: no time to put on it
            self.unstamped += 1
            return
        self._stamps_seen = self._stamps_seen or body is not None
        rgb = None
        if body is not None and frame.format.name == "yuv420p":
            yuv = frame.to_ndarray()
            if "crc" in body and zlib.crc32(yuv.tobytes()) != body["crc"]:  # damaged by a lost packet
                self.corrupt += 1
                return
            rgb = yuv420_to_rgb(yuv, int(body.get("w", 0)), int(body.get("h", 0)))
        if rgb is None:
            rgb = frame.to_ndarray(format="rgb24")
        if body is not None:
            t, stamped, sent = float(body["t"]), True, body.get("wall")
        else:
            t, stamped, sent = float(self.clock()), False, None
        got = StampedFrame(t, rgb, self.decoded, time.time(), sent if isinstance(sent, int | float) else None,
                           time.perf_counter() - t0, stamped)
        with self._cv:
            if stamped and self._ring and self._ring[-1].stamped and t < self._ring[-1].t - 1e-6:
                # time ran backwards: the SITL was restarted; its old frames are of another flight
                self._ring.clear()
                self.restarts += 1
            self._ring.append(got)
            self.decoded += 1
            self._cv.notify_all()

    # -- the FrameRequester's methods ---------------------------------------------------
    def ask(self, at_s: float) -> None:
        """Nothing to ask of a stream: the frame of at_s comes by itself (with an asker: ask
        the vehicle to capture, and hold, there)."""
        if self.asker is not None:
            self.asker(at_s)

    def frame_at(self, at_s: float) -> StampedFrame | None:
        """The first frame in the ring captured at or after at_s, None if none yet."""
        with self._cv:
            return self._first_at(at_s)

    def _first_at(self, at_s: float) -> StampedFrame | None:
        for f in self._ring:
            if f.t >= at_s - TOLERANCE_S:
                return f
        return None

    def wait_frame(self, at_s: float, timeout: float) -> StampedFrame | None:
        with self._cv:
            got: list[StampedFrame] = []

            def ready() -> bool:
                f = self._first_at(at_s)
                if f is not None:
                    got.append(f)
                return f is not None or self.ended

            self._cv.wait_for(ready, timeout)
            return got[0] if got else None

    def wait(self, at_s: float, timeout: float) -> tuple[np.ndarray | None, float | None]:
        """The first frame captured at or after at_s, and its capture time; (None, None) when
        none came within `timeout` wall seconds."""
        f = self.wait_frame(at_s, timeout)
        return (f.frame, f.t) if f is not None else (None, None)

    def capture(self, at_s: float, timeout: float = 1.5, tries: int = 8) -> tuple[np.ndarray | None, float | None]:
        """The frame of simulated time at_s: as wait, for up to timeout * tries seconds (the
        MAVLink requester's waits; with an asker, asked again each `timeout`, as it does)."""
        self.requests += 1
        if self.asker is None:
            return self.wait(at_s, timeout * tries)
        return ask_until_whole(self, at_s, timeout, tries)  # as the MAVLink camera asks: a lockstep SITL holds alike

    def request(self, timeout: float = 1.5, tries: int = 8) -> np.ndarray | None:
        """A frame decoded after this call, or None within timeout * tries seconds."""
        self.requests += 1
        with self._cv:
            n = self.decoded
            if self._cv.wait_for(lambda: self.decoded > n or self.ended, timeout * tries) and self.decoded > n:
                return self._ring[-1].frame
        return None

    def first_frame(self, timeout: float) -> StampedFrame:
        """The first decoded frame; VideoSourceError (naming the URL) when none comes within
        `timeout` wall seconds. An RTP stream opens without anything arriving (its SDP says
        all), so a companion checks here that the camera is on before it flies."""
        f = self.wait_frame(float("-inf"), timeout)
        if f is None and self.error is not None:
            raise self.error
        if f is None:
            raise VideoSourceError(f"camera {self.url}: no frame decoded within {timeout:g} s (is the stream "
                                   "running and sent to this machine's port?)")
        return f

    @property
    def latest(self) -> StampedFrame | None:
        with self._cv:
            return self._ring[-1] if self._ring else None

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=OPEN_RETRY_S + READ_TIMEOUT_S + 2.0)
        if not self._thread.is_alive() and self.container is not None:
            self.container.close()
        self._remove_temp()

    def _remove_temp(self) -> None:
        if self._in.temp is not None:
            self._in.temp.unlink(missing_ok=True)

    def __enter__(self) -> VideoSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def is_video_spec(spec: str) -> bool:
    """`run --camera SPEC` names a video source (not the MAVLink camera): a URL PyAV opens, an
    SDP file, a V4L2 device or a video file."""
    return not (spec == "mavlink" or spec.startswith("mavlink:"))


def open_video_source(spec: str, sdp: str | os.PathLike | None = None,
                      clock: Callable[[], float] = time.monotonic, first_frame_s: float | None = 30.0) -> VideoSource:
    """The camera source for `run --camera SPEC` (the camera package's open_source dispatches
    here for anything not MAVLink); `sdp`: an RTP stream's SDP file (the field file names it).
    Waits for a first frame (VideoSourceError naming the URL when none comes in first_frame_s)."""
    src = VideoSource(spec, sdp, clock)
    if first_frame_s is not None:
        try:
            src.first_frame(first_frame_s)
        except VideoSourceError:
            src.close()
            raise
    return src
