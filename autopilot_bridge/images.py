"""Where the camera frames' receiving side used to live; it is autopilot_bridge.camera now
(a camera source, never the autopilot). Re-exported so old imports keep working."""

from .camera.mavlink_camera import FrameRequester, MavlinkCamera
from .camera.png import TIME_KEY, FrameAssembler, decode_png, decode_png_stamped

__all__ = ["TIME_KEY", "FrameAssembler", "FrameRequester", "MavlinkCamera", "decode_png", "decode_png_stamped"]
