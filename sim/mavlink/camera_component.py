"""The simulated downward camera as a MAVLink camera component (camera protocol v2), as a
drone's camera is: component 100 (MAV_COMP_ID_CAMERA) of the vehicle's system, its own
HEARTBEAT (MAV_TYPE_CAMERA, MAV_AUTOPILOT_INVALID) at 1 Hz (of simulated time, and at least
of wall time), CAMERA_INFORMATION, CAMERA_SETTINGS, CAMERA_CAPTURE_STATUS and
VIDEO_STREAM_INFORMATION on request, and its frames over MAVLink's image transmission
protocol (images.py): a flight controller serves no frames (real PX4 answers
REQUEST_MESSAGE(DATA_TRANSMISSION_HANDSHAKE) with DENIED).

Frames: REQUEST_MESSAGE(DATA_TRANSMISSION_HANDSHAKE) asks for one now; its param 2 (ours,
like PX4's message-specific params), when > 0, for one captured at that simulated time (a
companion deciding on simulated time asks ahead; the PNG's tEXt "sim_time_s" says when it was
taken). A capture asked for again gets the same stamped picture, so a receiver on a lossy link
fills its gaps (FrameAssembler keeps chunks across handshakes of one picture); an untimed
request within FRAME_REUSE_S of the last picture, the vehicle not having moved, gets that
picture too. A receiver's own DATA_TRANSMISSION_HANDSHAKE asks for one frame; `rate_hz` > 0
streams them.

Two placements, one class: inside the SITL vehicle's process on the vehicle's links (as behind
a MAVLink router: `SharedLink`, the vehicle routes what arrives to `handle` and ticks the
camera after its own tick), or standalone on a UDP endpoint of its own (`UdpLink(...,
component_id=100)`), given the world's render function and simulated clock, run by `start()`
(its own thread) or by a host loop calling `service()` and `tick()`.

Broadcast: a command to component 0 that only a camera answers (REQUEST_MESSAGE of a camera
message or of a frame, the camera-protocol requests, IMAGE_START_CAPTURE) is taken by the
camera, and the autopilot beside it stays silent (`handle` returns True); everything else
addressed to 0 is left to the autopilot. A command addressed to component 100 is always the
camera's: answered UNSUPPORTED when it does not know it."""

from __future__ import annotations

import math
import select
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from .images import encode_png, png_messages
from .runner import BackgroundRunner

M = mavlink
MAV_COMP_ID_CAMERA = M.MAV_COMP_ID_CAMERA  # 100: the first camera of a system
MAX_PENDING_FRAMES = 2  # frame requests queued beyond this are answered by the frames already queued
#: a frame asked for again (untimed) within this many wall-clock seconds, the vehicle not having
#: moved more than FRAME_REUSE_M, is the same picture: resent as is so the receiver can fill its
#: gaps. A timed capture asked for again is always the picture of its time (see tick).
FRAME_REUSE_S = 3.0
FRAME_REUSE_M = 0.3
HEARTBEAT_HZ = 1.0
#: the heartbeat (on simulated time) runs at most this many times its rate in wall time, as
#: the vehicle's telemetry (streams.MAX_STREAM_SPEEDUP): a simulation racing ahead cannot flood
MAX_HEARTBEAT_SPEEDUP = 50.0
#: timed captures kept (the latest); a companion asks a few decisions ahead at most
MAX_TIMED = 8
SERVE_PERIOD_S = 0.002  # standalone: how often its thread looks at the clock between datagrams
#: the messages only a camera answers (REQUEST_MESSAGE's param 1)
CAMERA_MESSAGES = frozenset({
    M.MAVLINK_MSG_ID_CAMERA_INFORMATION, M.MAVLINK_MSG_ID_CAMERA_SETTINGS, M.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS,
    M.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE,
})
#: the camera protocol's own requests (deprecated by REQUEST_MESSAGE, still sent by ground stations)
REQUEST_COMMANDS = {
    M.MAV_CMD_REQUEST_CAMERA_INFORMATION: M.MAVLINK_MSG_ID_CAMERA_INFORMATION,
    M.MAV_CMD_REQUEST_CAMERA_SETTINGS: M.MAVLINK_MSG_ID_CAMERA_SETTINGS,
    M.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS: M.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS,
    M.MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION: M.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION,
}
CAMERA_COMMANDS = frozenset(REQUEST_COMMANDS) | {M.MAV_CMD_IMAGE_START_CAPTURE}


class Link(Protocol):
    """What the camera sends and polls through: `UdpLink` (a socket of its own, standalone) or
    `SharedLink` (the vehicle's socket; it polls nothing)."""

    mav: mavlink.MAVLink

    def send(self, msg: mavlink.MAVLink_message) -> None: ...
    def poll(self) -> list[mavlink.MAVLink_message]: ...
    def close(self) -> None: ...


def _text(value: str, size: int, name: str) -> bytes:
    data = value.encode("utf-8")
    if len(data) > size:
        raise ValueError(f"{name} is at most {size} bytes in MAVLink (got {len(data)}: {value!r})")
    return data


@dataclass(frozen=True)
class CameraInfo:
    """What CAMERA_INFORMATION and VIDEO_STREAM_INFORMATION say about the camera.

    video_uri: where the same camera's video stream is served (an RTP/H.264 stream, e.g.
    "udp://127.0.0.1:5600", served by another process): set, the camera says
    CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM and VIDEO_STREAM_INFORMATION carries it; None, it has
    no video stream."""

    vendor: str = "uavsearch"
    model: str = "sim downward camera"
    width: int = 50
    height: int = 50
    hfov_deg: float = 100.0  # sim.vehicle.camera.DownCamera's field of view
    video_uri: str | None = None
    video_framerate_hz: float = 10.0
    video_type: int = M.VIDEO_STREAM_TYPE_RTPUDP

    def __post_init__(self) -> None:
        _text(self.vendor, 32, "vendor")
        _text(self.model, 32, "model")
        if not (1 <= self.width <= 65535 and 1 <= self.height <= 65535):
            raise ValueError(f"resolution must be 1..65535 px a side (got {self.width} x {self.height})")
        if not 0 < self.hfov_deg < 360:
            raise ValueError(f"hfov_deg must be in (0, 360) (got {self.hfov_deg})")
        if self.video_uri is not None:
            if not self.video_uri:
                raise ValueError("video_uri must not be empty (None: no video stream)")
            _text(self.video_uri, 160, "video_uri")
        if not (math.isfinite(self.video_framerate_hz) and self.video_framerate_hz > 0):
            raise ValueError(f"video_framerate_hz must be > 0 (got {self.video_framerate_hz})")

    @property
    def flags(self) -> int:
        f = M.CAMERA_CAP_FLAGS_CAPTURE_IMAGE
        return f | M.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM if self.video_uri is not None else f


@dataclass
class CameraCounters:
    commands: int = 0
    denied: int = 0
    frames_sent: int = 0
    images_captured: int = 0  # fresh pictures taken (a resent one is not counted)


class CameraComponent(BackgroundRunner):
    """One MAVLink camera component; see the module docstring.

    render: the current view, (H, W, 3) uint8, rendered when a picture is taken. clock: the
    simulated time now (s), what captures are timed and stamped by. links: where it talks
    (`UdpLink(..., component_id=100)` standalone, `SharedLink` in the vehicle's process).
    position: where the camera is (NED m), for the untimed resend rule (None: every untimed
    request takes a fresh picture). rate_hz: frames streamed per second (0: on request only),
    read every tick. on_command: called for every command it takes (a lockstep SITL releases
    its clock there). on_decision_point: called when it sends a capture asked for ahead (a
    lockstep SITL holds its clock there until the companion's next command).
    wall_clock: for FRAME_REUSE_S and the heartbeat's wall-time cap."""

    def __init__(self, render: Callable[[], np.ndarray], clock: Callable[[], float], links: Sequence[Link],
                 system_id: int = 1, component_id: int = M.MAV_COMP_ID_CAMERA, info: CameraInfo | None = None,
                 position: Callable[[], np.ndarray] | None = None, rate_hz: Callable[[], float] | float = 0.0,
                 on_command: Callable[[], None] | None = None, on_decision_point: Callable[[], None] | None = None,
                 wall_clock: Callable[[], float] = time.monotonic) -> None:
        if not 1 <= system_id <= 255:
            raise ValueError(f"system_id must be in 1..255 (got {system_id})")
        if not 1 <= component_id <= 255:
            raise ValueError(f"component_id must be in 1..255 (got {component_id})")
        if not links:
            raise ValueError("a camera component needs at least one link")
        for link in links:
            if (link.mav.srcSystem, link.mav.srcComponent) != (system_id, component_id):
                raise ValueError(f"link sends as {link.mav.srcSystem}/{link.mav.srcComponent}, the camera is "
                                 f"{system_id}/{component_id}")
        self.render, self.clock, self.links = render, clock, list(links)
        self.sysid, self.compid = system_id, component_id
        self.info = info or CameraInfo()
        self.position, self.wall_clock = position, wall_clock
        self._rate = rate_hz if callable(rate_hz) else (lambda: float(rate_hz))
        self.on_command, self.on_decision_point = on_command, on_decision_point
        self.enc = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)  # builds, never sends
        self.counters = CameraCounters()
        self.t = 0.0
        self._pending = 0
        self._timed: list[float] = []  # simulated times of captures asked for ahead
        self._fresh = False  # the next frame must be captured anew (a timed capture)
        self._resend_timed = False  # the next frame answers a timed capture asked for again
        self._cache_t = -1.0  # simulated time the cached picture was taken at
        self._cache: tuple | None = None  # (wall time, position, PNG bytes, (h, w)) of the last picture
        self._next_frame_t = 0.0
        self._next_hb_t = 0.0
        self._last_hb_wall = -math.inf
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @classmethod
    def on_udp(cls, render: Callable[[], np.ndarray], clock: Callable[[], float], local_port: int,
               remote_port: int, system_id: int = 1, host: str = "127.0.0.1", bind: str = "0.0.0.0",
               signing_key: bytes | None = None, **kw) -> CameraComponent:
        """Standalone: a camera on a UDP endpoint of its own (bound to local_port, sending to
        host:remote_port and to whoever talks to it), e.g. beside a real autopilot binary;
        `start()` it. kw: the constructor's other options (info, position, rate_hz, ...)."""
        from .udp import UdpLink

        link = UdpLink(local_port, remote_port, host=host, system_id=system_id, component_id=M.MAV_COMP_ID_CAMERA,
                       signing_key=signing_key, bind=bind)
        try:
            return cls(render, clock, [link], system_id=system_id, **kw)
        except BaseException:
            link.close()
            raise

    # -- what arrives ----------------------------------------------------------------------
    def handle(self, msg: mavlink.MAVLink_message) -> bool:
        """Answer a message if it is the camera's; True when it took it (so the autopilot on
        the same link must not answer it too)."""
        if getattr(msg, "target_system", None) not in (None, 0, self.sysid):
            return False
        kind = msg.get_type()
        if kind == "DATA_TRANSMISSION_HANDSHAKE":
            # the image protocol's own request (it has no target: only a camera serves it): one
            # frame (PNG whatever type it names; our handshake says so)
            self.queue_frame()
            return True
        target = getattr(msg, "target_component", None)
        if kind not in ("COMMAND_LONG", "COMMAND_INT"):
            return target == self.compid  # addressed to the camera: nothing else is answered
        if target != self.compid and not (target == 0 and self._is_camera_command(msg)):
            return False
        self._on_command(msg)
        return True

    @staticmethod
    def _is_camera_command(msg: mavlink.MAVLink_message) -> bool:
        if msg.command == M.MAV_CMD_REQUEST_MESSAGE:
            return math.isfinite(msg.param1) and int(msg.param1) in CAMERA_MESSAGES
        return msg.command in CAMERA_COMMANDS

    def _on_command(self, msg: mavlink.MAVLink_message) -> None:
        self.counters.commands += 1
        if self.on_command is not None:
            self.on_command()
        p = (msg.param1, msg.param2, msg.param3, msg.param4)
        result, then = self._execute(msg.command, p)
        if result != M.MAV_RESULT_ACCEPTED:
            self.counters.denied += 1
        self.send(self.enc.command_ack_encode(msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))
        if then is not None:  # after the ACK, as the command protocol orders
            then()

    def _execute(self, cmd: int, p: tuple[float, ...]) -> tuple[int, Callable[[], None] | None]:
        if cmd in REQUEST_COMMANDS:
            return self._request(REQUEST_COMMANDS[cmd], (p[1] if cmd == M.MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION
                                                         else 0.0))
        if cmd == M.MAV_CMD_REQUEST_MESSAGE:
            if not math.isfinite(p[0]):
                return M.MAV_RESULT_DENIED, None
            return self._request(int(p[0]), p[1])
        if cmd == M.MAV_CMD_IMAGE_START_CAPTURE:
            # param 2 interval (s), param 3 total images: one picture now is all this camera takes
            if not (math.isfinite(p[2]) and int(p[2]) == 1):
                return M.MAV_RESULT_UNSUPPORTED, None
            return M.MAV_RESULT_ACCEPTED, self._capture_image
        return M.MAV_RESULT_UNSUPPORTED, None

    def _request(self, msg_id: int, p2: float) -> tuple[int, Callable[[], None] | None]:
        """REQUEST_MESSAGE(msg_id, p2): the result and what to send after the ACK."""
        if msg_id == M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE:
            if not math.isfinite(p2):
                return M.MAV_RESULT_DENIED, None
            if p2 > 0:  # a capture at this simulated time (s)
                return M.MAV_RESULT_ACCEPTED, lambda: self.capture_at(p2)
            return M.MAV_RESULT_ACCEPTED, self.queue_frame
        if msg_id == M.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION:
            if self.info.video_uri is None:
                return M.MAV_RESULT_UNSUPPORTED, None  # no video stream on this camera
            if not math.isfinite(p2) or int(p2) not in (0, 1):  # stream id: 0 all, 1 ours
                return M.MAV_RESULT_DENIED, None
        builders = {
            M.MAVLINK_MSG_ID_CAMERA_INFORMATION: self.camera_information,
            M.MAVLINK_MSG_ID_CAMERA_SETTINGS: self.camera_settings,
            M.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS: self.camera_capture_status,
            M.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION: self.video_stream_information,
            M.MAVLINK_MSG_ID_HEARTBEAT: self.heartbeat,
        }
        build = builders.get(msg_id)
        if build is None:
            return M.MAV_RESULT_UNSUPPORTED, None
        return M.MAV_RESULT_ACCEPTED, lambda: self.send(build())

    # -- what it says ----------------------------------------------------------------------
    def _boot_ms(self) -> int:
        return int(max(self.t, 0.0) * 1000) & 0xFFFFFFFF

    def heartbeat(self) -> mavlink.MAVLink_message:
        return self.enc.heartbeat_encode(M.MAV_TYPE_CAMERA, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)

    def camera_information(self) -> mavlink.MAVLink_message:
        i = self.info
        return self.enc.camera_information_encode(
            self._boot_ms(), list(_text(i.vendor, 32, "vendor").ljust(32, b"\0")),
            list(_text(i.model, 32, "model").ljust(32, b"\0")), 1, math.nan, math.nan, math.nan,
            i.width, i.height, 0, i.flags, 0, b"")

    def camera_settings(self) -> mavlink.MAVLink_message:
        return self.enc.camera_settings_encode(self._boot_ms(), M.CAMERA_MODE_IMAGE, math.nan, math.nan)

    def camera_capture_status(self) -> mavlink.MAVLink_message:
        # image_status 0 idle, video_status 0 idle; capacity unknown (no storage: frames go out)
        return self.enc.camera_capture_status_encode(self._boot_ms(), 0, 0, 0.0, 0, math.nan,
                                                     self.counters.images_captured)

    def video_stream_information(self) -> mavlink.MAVLink_message:
        i = self.info
        uri = _text(i.video_uri or "", 160, "video_uri")
        hfov = int(round(i.hfov_deg))
        return self.enc.video_stream_information_encode(
            1, 1, i.video_type, M.VIDEO_STREAM_STATUS_FLAGS_RUNNING, i.video_framerate_hz, i.width, i.height,
            0, 0, hfov, b"downward", uri, M.VIDEO_STREAM_ENCODING_H264)

    def send(self, msg: mavlink.MAVLink_message) -> None:
        for link in self.links:
            link.send(msg)

    # -- frames ----------------------------------------------------------------------------
    def capture_at(self, time_s: float) -> None:
        """Capture a frame on the first tick at or after simulated time `time_s` (at once if it
        has passed): a companion that decides on simulated time asks for its frames ahead."""
        self._timed = sorted([*self._timed, float(time_s)])[-MAX_TIMED:]

    def queue_frame(self) -> None:
        self._pending = min(self._pending + 1, MAX_PENDING_FRAMES)

    def _capture_image(self) -> None:
        """IMAGE_START_CAPTURE of one picture: a fresh one, announced by CAMERA_IMAGE_CAPTURED
        and sent over the image protocol at once (stamped with the clock now, not the last tick)."""
        self.t = self.clock()
        self._fresh = True
        self.queue_frame()
        self._send_frame()
        n = self.counters.images_captured
        self.send(self.enc.camera_image_captured_encode(self._boot_ms(), 0, 0, 0, 0, 0, 0, [1.0, 0.0, 0.0, 0.0],
                                                        n - 1, 1, b""))

    @property
    def busy(self) -> bool:
        """A frame is queued or a capture asked for ahead: the next tick must run."""
        return bool(self._pending or self._timed)

    def quiet_until(self) -> float | None:
        """Simulated time until which a tick would do nothing here (a fleet's quiet ticks skip
        it); None: the next tick must run."""
        if self.busy:
            return None
        until = self._next_hb_t
        if self._rate() > 0:
            until = min(until, self._next_frame_t)
        return until

    def tick(self, t: float | None = None) -> None:
        """At simulated time t (default: the clock's): the heartbeat when due, a capture asked
        for ahead when its time has come, a frame queued or due."""
        t = self.clock() if t is None else t
        self.t = t
        # on the lattice of simulated seconds, and at least once a wall-clock second (a world
        # whose clock stands still is not a camera gone), never faster than
        # MAX_HEARTBEAT_SPEEDUP x in wall time
        now = self.wall_clock()
        due_sim = t + 1e-9 >= self._next_hb_t
        if due_sim or now - self._last_hb_wall >= 1.0 / HEARTBEAT_HZ:
            if due_sim:
                self._next_hb_t = (math.floor((t + 1e-9) * HEARTBEAT_HZ) + 1.0) / HEARTBEAT_HZ
            if now - self._last_hb_wall >= 1.0 / (HEARTBEAT_HZ * MAX_HEARTBEAT_SPEEDUP):
                self._last_hb_wall = now
                self.send(self.heartbeat())
        if self._timed and t + 1e-9 >= self._timed[0]:
            due = self._timed.pop(0)
            # a capture asked for again (its frame lost on the way) gets the same stamped
            # picture, so the receiver can fill its gaps; a new time gets a new picture.
            # Asked again for a time the cached picture already answers: that picture, however
            # long ago on the wall clock (a 20 %-lossy link takes several asks of ~2.5 s each; a
            # new picture every 3 s threw away the chunks the receiver had, and a frame took 16 s)
            fresh = self._cache_t < due - 1e-6
            self._fresh = self._fresh or fresh
            self._resend_timed = self._resend_timed or not fresh
            self.queue_frame()
            if self.on_decision_point is not None:  # the companion decides on this frame
                self.on_decision_point()
        rate = self._rate()
        if self._pending or (rate > 0 and t >= self._next_frame_t):
            self._send_frame()

    def _send_frame(self) -> None:
        now = self.wall_clock()
        pos = None if self.position is None else np.asarray(self.position(), dtype=float)
        cached = self._cache
        if (self._pending and not self._fresh and cached is not None
                and (self._resend_timed or (pos is not None and cached[1] is not None
                                            and now - cached[0] <= FRAME_REUSE_S
                                            and np.linalg.norm(pos - cached[1]) <= FRAME_REUSE_M))):
            data, (h, w) = cached[2], cached[3]  # the same picture, with its own capture time
        else:
            self._fresh = False
            self._cache_t = self.t
            frame = self.render()
            data, (h, w) = encode_png(frame, self.t), frame.shape[:2]
            self._cache = (now, pos, data, (h, w))
            self.counters.images_captured += 1
        for m in png_messages(self.enc, data, w, h):
            self.send(m)
        self._resend_timed = False
        self.counters.frames_sent += 1
        self._pending = max(0, self._pending - 1)
        rate = self._rate()
        self._next_frame_t = self.t + (1.0 / rate if rate > 0 else 0.0)

    # -- standalone: its own sockets -------------------------------------------------------
    def service(self) -> None:
        """Answer what has arrived on links of its own (a SharedLink's owner routes instead)."""
        for link in self.links:
            for msg in link.poll():
                self.handle(msg)

    def run(self, duration: float | None = None) -> None:
        """Standalone: answer datagrams as they come and tick on the clock, until stopped."""
        socks = [link.sock for link in self.links if getattr(link, "owns_socket", True) and hasattr(link, "sock")]
        end = None if duration is None else self.wall_clock() + duration
        while not self._stop.is_set() and (end is None or self.wall_clock() < end):
            if socks:
                ready, _, _ = select.select(socks, [], [], SERVE_PERIOD_S)
                if ready:
                    self.service()
            else:
                time.sleep(SERVE_PERIOD_S)
            self.tick()

    def _thread_name(self) -> str:
        return f"camera-{self.sysid}-{self.compid}"

    def _close(self) -> None:
        for link in self.links:
            link.close()

    def close(self) -> None:
        """Stop its thread, if started, and close its links (a SharedLink leaves the vehicle's open)."""
        self.stop()
