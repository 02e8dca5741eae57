"""Camera sources: where the companion's frames come from. Never the autopilot (a flight
controller serves no frames): a MAVLink camera component (mavlink_camera.py) on the
vehicle's link or on its own address, or a video stream or device (other sources, opened by
scheme through `open_source`). Each is a `FrameSource` (source.py).

Specs (`uavsearch run --camera SPEC`):
  mavlink           the camera component on the vehicle's own link (default)
  mavlink:ADDRESS   the camera component on its own pymavlink address (udpin:0.0.0.0:14560, ...)
  udp://, rtsp://, /dev/video*, files   video sources: registered in SCHEMES by their module
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..link.connection import VehicleLink, check_address
from .mavlink_camera import CameraNotFound, CameraTarget, FrameRequester, MavlinkCamera
from .png import TIME_KEY, FrameAssembler, decode_png, decode_png_stamped
from .source import FrameSource, Stamped

__all__ = [
    "SCHEMES", "TIME_KEY", "CameraNotFound", "CameraSpecError", "CameraTarget", "FrameAssembler", "FrameRequester",
    "FrameSource", "check_spec", "MavlinkCamera", "Stamped", "decode_png", "decode_png_stamped", "open_source", "scheme_of",
]


class CameraSpecError(ValueError):
    """A --camera spec no source reads."""


#: opener(rest of the spec, the vehicle's link, options) -> FrameSource, by scheme (see scheme_of)
Opener = Callable[..., FrameSource]
SCHEMES: dict[str, Opener] = {}


def scheme_of(spec: str) -> tuple[str, str]:
    """(scheme, rest): "mavlink" / "mavlink:ADDRESS" -> ("mavlink", "" / ADDRESS); "udp://h:p",
    "rtsp://..." -> ("udp" / "rtsp", the whole spec); "/dev/video0" -> ("device", spec); any
    other text -> ("file", spec), a video file."""
    if spec == "mavlink" or spec.startswith("mavlink:"):
        return "mavlink", spec[len("mavlink:"):]
    if "://" in spec:
        return spec.split("://", 1)[0].lower(), spec
    if spec.startswith("/dev/"):
        return "device", spec
    return "file", spec


def _open_mavlink(rest: str, link: VehicleLink, link_address: str = "the vehicle's link",
                  signing_key: bytes | None = None, tlog: Path | None = None,
                  timeout_s: float = 5.0, **_: object) -> FrameSource:
    """The camera component on the vehicle's link (rest empty) or on its own address (checked by
    check_spec), found and described within timeout_s."""
    if not rest:
        cam = MavlinkCamera(link, where=link_address)
    else:
        cam = MavlinkCamera(VehicleLink(rest, tlog=tlog, signing_key=signing_key), where=rest, own_link=True)
    try:
        cam.discover(timeout_s)
    except BaseException:
        cam.close()
        raise
    return cam


SCHEMES["mavlink"] = _open_mavlink


def _open_video(rest: str, link: VehicleLink, sdp: str | Path | None = None, first_frame_s: float | None = 30.0,
                **_: object) -> FrameSource:
    """A video stream (video.py, PyAV): an RTP URL with its SDP, RTSP, a V4L2 device, a file;
    waits for its first frame (VideoSourceError naming the URL when none comes)."""
    from .video import open_video_source

    return open_video_source(rest, sdp, first_frame_s=first_frame_s)


for _scheme in ("udp", "rtp", "rtsp", "device", "file"):
    SCHEMES[_scheme] = _open_video


def check_spec(spec: str) -> None:
    """CameraSpecError for a spec no source reads (before anything is connected)."""
    scheme, rest = scheme_of(spec)
    if scheme not in SCHEMES:
        known = ", ".join(sorted(SCHEMES))
        raise CameraSpecError(f"no camera source reads {spec!r} (scheme {scheme!r}); known: {known} "
                              "(mavlink: the camera component on the vehicle's link; mavlink:ADDRESS: on its own)")
    if scheme == "mavlink" and rest:
        try:
            check_address(rest)
        except ValueError as e:
            raise CameraSpecError(f"--camera mavlink:{rest}: {e}") from None


def open_source(spec: str, link: VehicleLink, **options: object) -> FrameSource:
    """The frame source a --camera spec names, opened and ready (a MAVLink camera found and
    described: CameraNotFound when none answers). options go to the scheme's opener
    (link_address, signing_key, tlog, timeout_s for MAVLink)."""
    check_spec(spec)
    scheme, rest = scheme_of(spec)
    return SCHEMES[scheme](rest, link, **options)
