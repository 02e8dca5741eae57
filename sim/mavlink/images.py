"""Camera frames over MAVLink's image transmission protocol: a DATA_TRANSMISSION_HANDSHAKE
(type PNG, size, width, height, packet count) followed by ENCAPSULATED_DATA packets of 253
bytes. PNG keeps a 50 x 50 frame to ~4 kB (about 16 packets). The receiving side is
autopilot_bridge.images.FrameAssembler."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image
from pymavlink.dialects.v20 import common as mavlink

PAYLOAD = 253


def encode_png(frame: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(frame, dtype=np.uint8), "RGB").save(buf, format="PNG")
    return buf.getvalue()


def frame_messages(mav: mavlink.MAVLink, frame: np.ndarray) -> list[mavlink.MAVLink_message]:
    h, w = frame.shape[:2]
    return png_messages(mav, encode_png(frame), w, h)


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
