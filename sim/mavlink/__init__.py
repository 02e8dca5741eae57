"""The SITL vehicle's MAVLink side (PX4 or ArduCopter dialect: dialects/) and the lock-step runner."""

from .camera_component import CameraComponent, CameraInfo
from .component_link import SharedLink
from .fleet import SitlFleet
from .geofence import Geofence
from .images import encode_png, frame_messages
from .modes import px4_custom_mode, px4_mode_name
from .sitl import Sitl, SitlConfig
from .tlog import TlogWriter
from .udp import LinkStats, UdpLink
from .vehicle import MavlinkVehicle

__all__ = [
    "CameraComponent", "CameraInfo", "Geofence", "LinkStats", "MavlinkVehicle", "Sitl", "SitlConfig", "SitlFleet", "SharedLink", "TlogWriter",
    "UdpLink",
    "encode_png", "frame_messages", "px4_custom_mode", "px4_mode_name",
]
