"""The SITL vehicle's MAVLink side (PX4 flavour) and the lock-step runner."""

from .images import FrameAssembler, decode_png, encode_png
from .modes import px4_custom_mode, px4_mode_name
from .sitl import Sitl, SitlConfig
from .tlog import TlogWriter
from .vehicle import Geofence, MavlinkVehicle

__all__ = [
    "FrameAssembler", "Geofence", "MavlinkVehicle", "Sitl", "SitlConfig", "TlogWriter", "decode_png",
    "encode_png", "px4_custom_mode", "px4_mode_name",
]
