"""The SITL camera as a real drone's: an RTP/H.264 video stream on UDP (PX4's Gazebo streams
its camera to port 5600, which QGroundControl shows as "UDP h.264 Video Stream").

The downward camera's frames (50 x 50 px) are scaled up by an integer factor (nearest
neighbour, 4x: 200 x 200) so H.264's 4:2:0 chroma, one colour sample per 2 x 2 pixels, keeps
every camera pixel's colour; the receiver averages each block back (autopilot_bridge/camera/
video.py). Encoded with libx264 (the encoder PyAV's wheel ships), tuned for low latency and
fidelity: zerolatency (no B-frames, no look-ahead: one packet out per frame in), a constant
quantiser (0, lossless, by default: see VideoConfig.qp), colours converted exactly (to_yuv420), a keyframe every `keyint` frames so a receiver that joins late starts within a
second, SPS/PPS repeated before each keyframe.

The time stamps. Every frame carries its capture time on the simulated clock twice:
  - the RTP timestamp is round(sim_time_s * 90000) mod 2**32 (origin: simulated time 0, not
    a random offset), for any RTP tool; FFmpeg's demuxer hides it (it rebases pts on the first
    packet it hears), so it alone cannot serve a receiver that joins late;
  - a user-data-unregistered SEI (H.264 payload type 5) before each picture, with the UUID
    SEI_UUID and a JSON body {"t": sim_time_s (repr, exact), "n": frame index, "w", "h": the
    camera's own size, "wall": the sender's time.time() at capture, "crc": CRC-32 of the
    frame's Y, U, V planes when the encoding is lossless}, which FFmpeg hands the decoder's
    frame as SEI_UNREGISTERED side data: the exact capture time of each frame, and a check
    that the decoded frame is the captured one. A lost packet damages its frame and, through
    prediction, those after it up to the next keyframe; FFmpeg conceals the damage and flags
    few of them (2 of 17 damaged frames at 2 % loss), the CRC catches every one.

Packetised here (RFC 6184, packetization-mode 1: single NAL units, FU-A fragments; the marker
bit on each access unit's last packet), rather than by FFmpeg's RTP muxer, which draws a random
timestamp origin and cannot put a per-frame SEI in. Frames are rendered on the simulation's
thread (PyBullet is not thread-safe) and encoded and sent on a worker thread; a worker that
falls behind drops the oldest waiting frame (counted) rather than slowing the simulation.
"""

from __future__ import annotations

import json
import logging
import math
import socket
import threading
import time
import zlib
from collections import deque
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

from provenance import atomic_write_bytes

log = logging.getLogger(__name__)

RTP_CLOCK_HZ = 90000
PAYLOAD_TYPE = 96
#: the UUID of our time-stamp SEI (user data unregistered); no zero bytes, so no emulation
#: prevention inside it
SEI_UUID = bytes.fromhex("75617673656172636874696d65763031")  # "uavsearchtimev01"
DEFAULT_VIDEO_PORT = 5600
#: an access unit delimiter (primary_pic_type 7: any slice types), sent after each frame
AUD = bytes([0x09, 0xF0])
MAX_QUEUED = 4  # frames waiting for the encoder; beyond this the oldest is dropped


@dataclass(frozen=True)
class VideoConfig:
    """The video stream: where to (port 0: off), how often (simulated Hz) and how well."""

    port: int = 0
    host: str = "127.0.0.1"
    rate_hz: float = 10.0
    scale: int = 4  # integer upscaling (nearest): 50 px -> 200 px
    #: libx264's constant quantiser: 0 is lossless (High 4:4:4 Predictive profile, which FFmpeg
    #: and so QGroundControl's software decoder read; some hardware decoders do not: use 4, High
    #: profile, colours within 5 levels). 120 rendered views with cows: the detector's blobs on
    #: the decoded frames were those of the PNG frames in 60 of 60 at qp 0 (within a level of
    #: colour), 59-60 of 60 at 4, 59 at 12 (5 levels); swscale's own conversion: 36 of 60
    qp: int = 0
    keyint: int = 10  # a keyframe every this many frames (1 s at 10 Hz)
    preset: str = "ultrafast"
    mtu: int = 1200  # bytes of RTP payload per datagram at most
    #: at most this many frames per wall-clock second: a simulation running faster than
    #: max_wall_hz / rate_hz (10x at the defaults) leaves lattice frames out rather than spend its
    #: time rendering them (as fast as it goes, 276x without the stream, 43x rendering them all)
    max_wall_hz: float = 100.0
    ssrc: int = 0x55415653

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ValueError(f"video port must be 0 (off) or a UDP port 1..65535 (got {self.port})")
        if not (math.isfinite(self.rate_hz) and 0 < self.rate_hz <= 60):
            raise ValueError(f"video rate must be in (0, 60] Hz of simulated time (got {self.rate_hz})")
        if not 1 <= self.scale <= 16:
            raise ValueError(f"video scale must be an integer 1..16 (got {self.scale})")
        if not 0 <= self.qp <= 51:
            raise ValueError(f"video qp must be 0..51 (got {self.qp})")
        if not 1 <= self.keyint <= 600:
            raise ValueError(f"video keyint must be 1..600 frames (got {self.keyint})")
        if not self.max_wall_hz > 0:
            raise ValueError(f"video max_wall_hz must be > 0 (got {self.max_wall_hz})")
        if not 200 <= self.mtu <= 65000:
            raise ValueError(f"video mtu must be 200..65000 bytes (got {self.mtu})")
        try:
            socket.inet_aton(self.host)
        except OSError:
            raise ValueError(f"video host must be an IPv4 address such as 127.0.0.1 (got {self.host!r})") from None

    @property
    def enabled(self) -> bool:
        return self.port > 0


def rtp_timestamp(sim_time_s: float) -> int:
    """The RTP timestamp of a frame captured at sim_time_s: 90 kHz ticks from simulated 0."""
    return round(sim_time_s * RTP_CLOCK_HZ) % (1 << 32)


def _escape(rbsp: bytes) -> bytes:
    """H.264 emulation prevention: 00 00 0x (x <= 3) -> 00 00 03 0x."""
    out, zeros = bytearray(), 0
    for b in rbsp:
        if zeros >= 2 and b <= 3:
            out.append(3)
            zeros = 0
        out.append(b)
        zeros = zeros + 1 if b == 0 else 0
    return bytes(out)


def time_sei(body: dict) -> bytes:
    """A user-data-unregistered SEI NAL unit (no start code) carrying `body` as JSON."""
    payload = SEI_UUID + json.dumps(body, separators=(",", ":")).encode("ascii")
    size, head = len(payload), bytearray([5])  # payload type 5
    while size >= 255:
        head.append(255)
        size -= 255
    head.append(size)
    return bytes([0x06]) + _escape(bytes(head) + payload + b"\x80")


def split_annexb(data: bytes) -> list[bytes]:
    """An Annex B byte stream -> its NAL units (start codes removed)."""
    nals, i, n = [], 0, len(data)
    starts = []
    while True:
        j = data.find(b"\x00\x00\x01", i)
        if j < 0:
            break
        starts.append(j + 3)
        i = j + 3
    for k, s in enumerate(starts):
        end = starts[k + 1] - 3 if k + 1 < len(starts) else n
        nal = data[s:end]
        while nal.endswith(b"\x00") and k + 1 < len(starts):  # a 4-byte start code's leading zero
            nal = nal[:-1]
        if nal:
            nals.append(nal)
    return nals


class RtpPacketizer:
    """RFC 6184 packetization mode 1: a NAL unit that fits goes out whole, a larger one in FU-A
    fragments; the last packet of a frame has the marker bit."""

    def __init__(self, ssrc: int, mtu: int, payload_type: int = PAYLOAD_TYPE) -> None:
        self.ssrc, self.mtu, self.pt, self.seq = ssrc, mtu, payload_type, 0

    def _header(self, ts: int, marker: bool) -> bytes:
        self.seq = (self.seq + 1) & 0xFFFF
        return bytes([0x80, (0x80 if marker else 0) | self.pt]) + self.seq.to_bytes(2, "big") + \
            ts.to_bytes(4, "big") + self.ssrc.to_bytes(4, "big")

    def packets(self, nals: list[bytes], ts: int) -> list[bytes]:
        out: list[bytes] = []
        for i, nal in enumerate(nals):
            last = i == len(nals) - 1
            if len(nal) <= self.mtu:
                out.append(self._header(ts, last) + nal)
                continue
            indicator = (nal[0] & 0xE0) | 28  # FU-A, the NAL's F and NRI bits
            kind, body, step = nal[0] & 0x1F, nal[1:], self.mtu - 2
            for off in range(0, len(body), step):
                start, end = off == 0, off + step >= len(body)
                fu_header = (0x80 if start else 0) | (0x40 if end else 0) | kind
                out.append(self._header(ts, last and end) + bytes([indicator, fu_header]) + body[off:off + step])
        return out


class H264Encoder:
    """libx264 through PyAV: RGB frames in, NAL units out, one access unit per frame."""

    def __init__(self, width: int, height: int, cfg: VideoConfig) -> None:
        import av

        if width % 2 or height % 2:
            raise ValueError(f"H.264 4:2:0 needs even frame sizes (got {width} x {height}): pick another scale")
        self.width, self.height = width, height
        ctx = av.CodecContext.create("libx264", "w")
        ctx.width, ctx.height, ctx.pix_fmt = width, height, "yuv420p"
        ctx.colorspace, ctx.color_range = 6, 1  # SMPTE 170M (BT.601), limited: what to_yuv420 writes
        ctx.time_base = Fraction(1, RTP_CLOCK_HZ)
        ctx.framerate = Fraction(round(cfg.rate_hz * 1000), 1000)
        ctx.gop_size = cfg.keyint
        ctx.max_b_frames = 0
        ctx.options = {"preset": cfg.preset, "tune": "zerolatency", "qp": str(cfg.qp),
                       "x264-params": f"keyint={cfg.keyint}:min-keyint={cfg.keyint}:scenecut=0:repeat-headers=1:"
                                      "bframes=0:sliced-threads=0:threads=1"}
        ctx.open()
        self.ctx = ctx
        self._av = av

    def encode(self, yuv: np.ndarray, pts: int) -> list[bytes]:
        """yuv: (H * 3 / 2, W) uint8 planes Y, U, V (to_yuv420)."""
        frame = self._av.VideoFrame.from_ndarray(yuv, format="yuv420p")
        frame.pts = pts
        nals: list[bytes] = []
        for packet in self.ctx.encode(frame):
            nals.extend(split_annexb(bytes(packet)))
        return nals


def to_yuv420(rgb: np.ndarray, scale: int) -> np.ndarray:
    """RGB (h, w, 3) -> BT.601 limited-range 4:2:0 planes of the frame scaled up `scale` times
    (nearest), as the (H * 3 / 2, W) array PyAV takes. Done here in floating point rather than by
    swscale, whose integer RGB -> YUV -> RGB with interpolated chroma moved colours by up to 15
    levels at a cow's outline (a lossless encode included) and the detector's blob sizes by up
    to 20 px; this way a lossless round trip is off by a level at most."""
    f = rgb.astype(np.float32)
    r, g, b = f[..., 0], f[..., 1], f[..., 2]
    y = 16.0 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0
    u = 128.0 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0
    v = 128.0 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0
    planes = []
    for k, p in enumerate((y, u, v)):
        big = np.repeat(np.repeat(p, scale, axis=0), scale, axis=1)
        if k:  # one chroma sample per 2 x 2 pixels: their mean
            hh, ww = big.shape
            big = big.reshape(hh // 2, 2, ww // 2, 2).mean(axis=(1, 3))
        planes.append(np.clip(np.rint(big), 0, 255).astype(np.uint8))
    h, w = planes[0].shape
    return np.concatenate([planes[0], planes[1].reshape(h // 4, w), planes[2].reshape(h // 4, w)])


class VideoStreamer:
    """Streams frames (RGB, with their simulated capture times) as RTP/H.264 to host:port;
    `submit` returns at once, a worker thread scales, encodes and sends."""

    def __init__(self, cfg: VideoConfig, width: int, height: int) -> None:
        if not cfg.enabled:
            raise ValueError("VideoStreamer needs a video port (port 0 is off)")
        self.cfg, self.width, self.height = cfg, width, height
        self.out_w, self.out_h = width * cfg.scale, height * cfg.scale
        self.encoder = H264Encoder(self.out_w, self.out_h, cfg)
        self.rtp = RtpPacketizer(cfg.ssrc, cfg.mtu)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
        self.addr = (cfg.host, cfg.port)
        self._queue: deque[tuple[np.ndarray, float, float]] = deque()
        self._cv = threading.Condition()
        self._stop = False
        self.frames_sent = 0
        self.frames_dropped = 0  # the worker fell behind: the oldest waiting frame was left out
        self.send_errors = 0
        self.bytes_sent = 0  # RTP payload and headers
        #: the last frames sent and their capture times (what a receiver should decode: tests, benchmarks)
        self.recent: deque[tuple[float, np.ndarray]] = deque(maxlen=64)
        self.encode_s: list[float] = []  # wall seconds per frame: scale + encode + packetise + send
        self._next_t = 0.0  # the next frame's time on the lattice k / rate_hz
        self._next_wall = 0.0  # no frame before this (time.monotonic(): max_wall_hz)
        self.frames_skipped = 0  # lattice frames left out: the simulation ran past max_wall_hz
        self._thread = threading.Thread(target=self._work, name="video-stream", daemon=True)
        self._thread.start()

    # -- the simulation's side ---------------------------------------------------------
    def due(self, t: float) -> bool:
        """A frame is due at simulated time t (the lattice k / rate_hz, first tick on or after),
        unless the last one went out less than 1 / max_wall_hz wall seconds ago (then this
        lattice point is left out, counted in frames_skipped)."""
        if t + 1e-9 < self._next_t:
            return False
        if time.monotonic() < self._next_wall:
            self._next_t = (math.floor(t * self.cfg.rate_hz + 1e-6) + 1) / self.cfg.rate_hz
            self.frames_skipped += 1
            return False
        return True

    def submit(self, frame: np.ndarray, t: float) -> None:
        """Queue a frame captured at simulated time t; never blocks."""
        self._next_t = (math.floor(t * self.cfg.rate_hz + 1e-6) + 1) / self.cfg.rate_hz
        self._next_wall = time.monotonic() + 1.0 / self.cfg.max_wall_hz
        with self._cv:
            if len(self._queue) >= MAX_QUEUED:
                self._queue.popleft()
                self.frames_dropped += 1
            self._queue.append((frame, t, time.time()))
            self._cv.notify()

    def close(self) -> None:
        with self._cv:
            self._stop = True
            self._cv.notify()
        self._thread.join(timeout=5)
        self.sock.close()

    # -- the worker ---------------------------------------------------------------------
    def _work(self) -> None:
        n = 0
        while True:
            with self._cv:
                self._cv.wait_for(lambda: self._queue or self._stop)
                if self._stop:
                    return
                frame, t, wall = self._queue.popleft()
            t0 = time.perf_counter()
            try:
                self._send(frame, t, n, wall)
                n += 1
            except Exception:  # a broken frame or a closed socket must not kill the stream
                self.send_errors += 1
                log.exception("video frame at %.2f s not sent", t)
            self.encode_s.append(time.perf_counter() - t0)
            if len(self.encode_s) > 10000:
                del self.encode_s[:5000]

    def _send(self, frame: np.ndarray, t: float, n: int, wall: float) -> None:
        ts = rtp_timestamp(t)
        yuv = to_yuv420(frame, self.cfg.scale)
        nals = self.encoder.encode(yuv, round(t * RTP_CLOCK_HZ))
        if not nals:
            return
        body = {"t": t, "n": n, "w": self.width, "h": self.height, "wall": wall}
        if self.cfg.qp == 0:  # lossless: the decoded planes are these bytes, or the frame was damaged
            body["crc"] = zlib.crc32(yuv.tobytes())
        sei = time_sei(body)
        # the SEI before the picture's slices, after any SPS/PPS (an access unit's order)
        k = next((i for i, x in enumerate(nals) if x[0] & 0x1F in (1, 5)), len(nals))
        # and an access unit delimiter after them: FFmpeg's H.264 parser (which its RTP demuxer
        # runs) hands a frame on only when it sees the next one begin, a frame period late
        # (108 ms at 10 Hz on loopback); the delimiter begins "the next" at once (4 ms)
        nals = [*nals[:k], sei, *nals[k:], AUD]
        for pkt in self.rtp.packets(nals, ts):
            self.bytes_sent += len(pkt)
            try:
                self.sock.sendto(pkt, self.addr)
            except OSError:  # nobody listening (ICMP refused) is no error for a stream
                self.send_errors += 1
        self.frames_sent += 1
        self.recent.append((t, frame))

    # -- describing the stream ----------------------------------------------------------
    def sdp(self, name: str = "uavsearch SITL camera") -> str:
        """The session description a receiver (FFmpeg, VLC, GStreamer) needs for this stream."""
        return sdp_text(self.cfg, name)

    def write_sdp(self, path: Path) -> Path:
        atomic_write_bytes(Path(path), self.sdp().encode("ascii"))
        return Path(path)


def sdp_text(cfg: VideoConfig, name: str = "uavsearch SITL camera") -> str:
    """SDP for the stream (RFC 4566 / 6184). The receiver binds the m= port; c= names the
    address the stream is sent to. SPS/PPS travel in-band before every keyframe."""
    return "\r\n".join([
        "v=0",
        f"o=- 0 0 IN IP4 {cfg.host}",
        f"s={name}",
        f"c=IN IP4 {cfg.host}",
        "t=0 0",
        f"m=video {cfg.port} RTP/AVP {PAYLOAD_TYPE}",
        f"a=rtpmap:{PAYLOAD_TYPE} H264/{RTP_CLOCK_HZ}",
        f"a=fmtp:{PAYLOAD_TYPE} packetization-mode=1",
        f"a=framerate:{cfg.rate_hz:g}",
        "a=recvonly",
        "",
    ])
