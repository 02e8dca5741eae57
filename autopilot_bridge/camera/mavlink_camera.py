"""The camera as a MAVLink camera component (camera protocol v2): found on a link by its
HEARTBEAT (MAV_TYPE_CAMERA; system and component id from the packet) and asked for
CAMERA_INFORMATION, then asked for frames over the image transmission protocol
(MAV_CMD_REQUEST_MESSAGE(DATA_TRANSMISSION_HANDSHAKE) addressed to it; param 2, when > 0, the
simulated instant to capture at, which the simulated camera honours and stamps into the PNG).

The camera may share the autopilot's link (a drone's MAVLink router: one address, two
components) or sit on a link of its own (`--camera mavlink:ADDRESS`): either way its commands
and their ACKs are its own, addressed to its component and answered by it, never the
autopilot's (the link leaves ACKs from other components to their senders). A frame is
collected on the link's receive thread and asked for again until whole (the camera resends
the same stamped picture, and the assembler fills its gaps).
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

import numpy as np

# the camera protocol's ids (mavutil's default MAVLink 1 dialect lacks them)
from pymavlink.dialects.v20 import common as mavlink

from ..link.connection import CommandRejected, LinkError, VehicleLink, resend_until_acked
from .png import FrameAssembler
from .source import Stamped, ask_until_whole

log = logging.getLogger(__name__)
DISCOVER_TIMEOUT_S = 5.0  # wall seconds a camera has to heartbeat (1 Hz) before it is missing
INFO_TIMEOUT_S = 2.0  # ... and to send CAMERA_INFORMATION once asked
#: the vehicle's own clock (its telemetry's time_boot_ms) ran this long on the link with no
#: camera heartbeat (1 Hz): there is none, said at once rather than after DISCOVER_TIMEOUT_S of
#: wall time (a camera-less SITL at 40x has flown 200 s by then)
ABSENT_AFTER_S = 5.0
#: the component ids MAVLink gives cameras (MAV_COMP_ID_CAMERA .. CAMERA6)
CAMERA_COMPONENTS = range(mavlink.MAV_COMP_ID_CAMERA, mavlink.MAV_COMP_ID_CAMERA6 + 1)


class CameraNotFound(LinkError):
    """No MAVLink camera component answered on the link."""


@dataclass(frozen=True)
class CameraTarget:
    """Which component is the camera, and what it said about itself (CAMERA_INFORMATION;
    empty when it heartbeats but did not say)."""

    system_id: int
    component_id: int
    vendor: str = ""
    model: str = ""
    resolution: tuple[int, int] | None = None  # (width, height) px
    flags: int = 0  # CAMERA_CAP_FLAGS

    def describe(self) -> str:
        what = f"{self.vendor} {self.model}".strip() or "a camera"
        size = f", {self.resolution[0]} x {self.resolution[1]} px" if self.resolution else ""
        return f"{what} (MAVLink {self.system_id}/{self.component_id}{size})"


def is_camera_heartbeat(msg) -> bool:
    return msg.get_type() == "HEARTBEAT" and (msg.type == mavlink.MAV_TYPE_CAMERA or (
        msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID and msg.get_srcComponent() in CAMERA_COMPONENTS
        and msg.type not in (mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER)))


def _text(chars) -> str:
    raw = bytes(chars) if not isinstance(chars, (bytes, str)) else chars
    if isinstance(raw, str):
        return raw.rstrip("\0")
    return raw.split(b"\0", 1)[0].decode("utf-8", errors="replace")


class MavlinkCamera:
    """A FrameSource (source.py) on a MAVLink camera component.

    link: the VehicleLink it listens and sends on (the vehicle's, or one of the camera's own).
    target: the camera, when known; None: the first camera heartbeat on the link (of the
    vehicle's system when the link knows it), waited for at the first ask. where: how the
    link is reached, for the error that no camera answered. own_link: close the link with
    the source (a connection opened for the camera alone)."""

    timed_captures = True

    def __init__(self, link: VehicleLink, target: CameraTarget | None = None, where: str = "the vehicle's link",
                 own_link: bool = False, discover_timeout_s: float = DISCOVER_TIMEOUT_S) -> None:
        self.link, self.target, self.where, self.own_link = link, target, where, own_link
        self.discover_timeout_s = discover_timeout_s
        self.asm = FrameAssembler()
        self.latest: np.ndarray | None = None
        self.latest_time_s: float | None = None
        self.event = threading.Event()
        self.requests = 0
        self.command_retries = 0
        self._cv = threading.Condition()
        self._heard: list[tuple[int, int]] = []  # camera components heard, in order
        self._info: dict[tuple[int, int], CameraTarget] = {}
        self._acks: dict[int, int] = {}
        self._vehicle_t0: float | None = None  # the vehicle's clock (s) when its telemetry was first heard
        self._absent = False  # that clock ran ABSENT_AFTER_S with no camera heartbeat
        self._closed = False
        link.add_handler(self._on_message)

    # -- the receive thread ----------------------------------------------------------------
    def _on_message(self, msg) -> None:
        if self._closed:
            return
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            if is_camera_heartbeat(msg) and src not in self._heard:
                with self._cv:
                    self._heard.append(src)
                    self._cv.notify_all()
            return
        if src[1] not in CAMERA_COMPONENTS and not self._heard and not self._absent:
            boot_ms = getattr(msg, "time_boot_ms", None)  # the vehicle's clock, while no camera is heard
            if boot_ms is not None:
                t = boot_ms * 1e-3
                if self._vehicle_t0 is None:
                    self._vehicle_t0 = t
                elif t - self._vehicle_t0 >= ABSENT_AFTER_S:
                    with self._cv:
                        self._absent = True
                        self._cv.notify_all()
        target = self.target
        if kind == "CAMERA_INFORMATION":
            with self._cv:
                self._info[src] = CameraTarget(*src, _text(msg.vendor_name), _text(msg.model_name),
                                               (msg.resolution_h, msg.resolution_v), msg.flags)
                self._cv.notify_all()
            return
        if target is None or src != (target.system_id, target.component_id):
            return
        if kind == "COMMAND_ACK":
            with self._cv:
                self._acks[msg.command] = msg.result
                self._cv.notify_all()
        elif kind in ("DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA"):
            frame = self.asm.feed(msg)
            if frame is not None:
                with self._cv:
                    self.latest, self.latest_time_s = frame, self.asm.last_time_s
                    self.event.set()
                    self._cv.notify_all()

    # -- finding the camera ----------------------------------------------------------------
    def _pick(self) -> tuple[int, int] | None:
        """The camera heard: of the vehicle's system when the link knows it, else the first."""
        if not self._heard:
            return None
        sysid = self.link.conn.target_system
        mine = [h for h in self._heard if h[0] == sysid]
        return (mine or self._heard)[0]

    def _not_found(self) -> CameraNotFound:
        within = (f"in {ABSENT_AFTER_S:g} s of the vehicle's clock" if self._absent
                  else f"within {self.discover_timeout_s:g} s")
        return CameraNotFound(f"no MAVLink camera component answered on {self.where} {within}: is the camera "
                              "running? --camera mavlink (on the vehicle's link) or --camera mavlink:ADDRESS (its own)")

    def _require_target(self) -> CameraTarget:
        """The camera, waiting for its heartbeat if none has come yet; CameraNotFound when none
        comes within discover_timeout_s, or the vehicle's clock runs ABSENT_AFTER_S without one."""
        if self.target is not None:
            return self.target
        with self._cv:
            self._cv.wait_for(lambda: self._pick() is not None or self._absent, self.discover_timeout_s)
            picked = self._pick()
            if picked is None:
                raise self._not_found()
            self.target = self._info.get(picked) or CameraTarget(*picked)
        log.info("camera: %s on %s", self.target.describe(), self.where)
        return self.target

    def discover(self, timeout_s: float | None = None) -> CameraTarget:
        """Find the camera (its heartbeat) and ask it for CAMERA_INFORMATION; the target, with
        what it said. Raises CameraNotFound when no camera heartbeats within timeout_s. A camera
        that heartbeats but does not describe itself is used all the same (logged)."""
        if timeout_s is not None:
            self.discover_timeout_s = timeout_s
        target = self._require_target()
        key = (target.system_id, target.component_id)
        if key not in self._info:
            try:
                self._command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION,
                              timeout=0.5, retries=4)
                with self._cv:
                    self._cv.wait_for(lambda: key in self._info, INFO_TIMEOUT_S)
            except (CommandRejected, LinkError) as e:
                log.warning("camera %s did not send CAMERA_INFORMATION (%s): used as it is", target.describe(), e)
        if key in self._info:
            self.target = self._info[key]
        return self.target

    # -- commands to the camera ------------------------------------------------------------
    def _command(self, cmd: int, *params: float, timeout: float = 0.5, retries: int = 10) -> int:
        """COMMAND_LONG to the camera, resent (confirmation + 1) with a growing wait until its
        ACK comes, as VehicleLink.command does for the autopilot; MAV_RESULT_ACCEPTED or
        CommandRejected / LinkError."""
        target = self._require_target()
        p = list(params) + [0.0] * (7 - len(params))

        def send(confirmation: int) -> None:
            if confirmation:
                self.command_retries += 1
            self.link.send_command_long((target.system_id, target.component_id), cmd, confirmation, *p)

        result, tries = resend_until_acked(send, self._cv, self._acks, cmd, timeout, retries, 30.0,
                                           self.link.silent_for)
        if result is None:
            raise LinkError(f"no COMMAND_ACK from the camera {target.describe()} for command {cmd} after {tries} "
                            f"tries{self.link.silence_note()}")
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise CommandRejected(cmd, result)
        return result

    # -- frames (FrameSource) --------------------------------------------------------------
    def ask(self, at_s: float) -> None:
        """Ask for a frame captured at simulated time at_s (ahead of time; REQUEST_MESSAGE's
        param 2, which the simulated camera reads as the capture time)."""
        self.requests += 1
        self._command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE, float(at_s))

    def wait(self, at_s: float, timeout: float) -> Stamped:
        """The first frame captured at or after at_s (an unstamped frame is taken as it comes)."""
        def ok() -> bool:
            return self.latest is not None and (self.latest_time_s is None or self.latest_time_s >= at_s - 1e-3)

        with self._cv:
            if self._cv.wait_for(ok, timeout):
                return self.latest, self.latest_time_s
        return None, None

    def capture(self, at_s: float, timeout: float = 1.5, tries: int = 8) -> Stamped:
        """The frame captured at simulated time at_s, asking again (the camera resends the
        same stamped picture) until it is whole or the tries run out; (None, None) then."""
        return ask_until_whole(self, at_s, timeout, tries)

    def request(self, timeout: float = 1.5, tries: int = 8) -> np.ndarray | None:
        """A fresh frame, or None when `tries` requests of `timeout` seconds each brought none."""
        self.event.clear()
        for _ in range(tries):
            self.requests += 1
            self._command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE)
            if self.event.wait(timeout):
                return self.latest
        return None

    def close(self) -> None:
        self._closed = True
        if self.own_link:
            self.link.close()


#: the name it had when the autopilot served the frames (autopilot_bridge.camera)
FrameRequester = MavlinkCamera
