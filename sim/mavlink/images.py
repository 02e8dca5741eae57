"""Camera frames over MAVLink's image transmission protocol: a DATA_TRANSMISSION_HANDSHAKE
(type PNG, size, width, height, packet count) followed by ENCAPSULATED_DATA packets of 253
bytes. PNG keeps a 50 x 50 frame to ~4 kB (about 16 packets). The receiving side is
autopilot_bridge.camera.FrameAssembler.

Each PNG carries the simulated time it was captured at in a tEXt chunk ("sim_time_s"), so a
receiver can match a frame to telemetry and GPS fixes of the same instant (the image
protocol itself has no timestamp field)."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image, PngImagePlugin
from pymavlink.dialects.v20 import common as mavlink

PAYLOAD = 253
#: the PNG tEXt key holding the capture's simulated time in seconds
TIME_KEY = "sim_time_s"


def encode_png(frame: np.ndarray, time_s: float | None = None) -> bytes:
    buf = io.BytesIO()
    info = None
    if time_s is not None:
        info = PngImagePlugin.PngInfo()
        info.add_text(TIME_KEY, f"{time_s:.6f}")
    Image.fromarray(np.ascontiguousarray(frame, dtype=np.uint8), "RGB").save(buf, format="PNG", pnginfo=info)
    return buf.getvalue()


def frame_messages(mav: mavlink.MAVLink, frame: np.ndarray, time_s: float | None = None) -> list[mavlink.MAVLink_message]:
    h, w = frame.shape[:2]
    return png_messages(mav, encode_png(frame, time_s), w, h)


def png_messages(mav: mavlink.MAVLink, data: bytes, w: int, h: int) -> list[mavlink.MAVLink_message]:
    """One PNG as a handshake and its ENCAPSULATED_DATA packets."""
    packets = -(-len(data) // PAYLOAD)
    msgs: list[mavlink.MAVLink_message] = [
        mav.data_transmission_handshake_encode(mavlink.MAVLINK_DATA_STREAM_IMG_PNG, len(data), w, h, packets, PAYLOAD, 0)
    ]
    for i in range(packets):
        chunk = data[i * PAYLOAD : (i + 1) * PAYLOAD]
        msgs.append(mav.encapsulated_data_encode(i, chunk.ljust(PAYLOAD, b"\0")))
    return msgs
