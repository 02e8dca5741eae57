"""Camera frames over MAVLink's image transmission protocol: a DATA_TRANSMISSION_HANDSHAKE
(type PNG, size, width, height, packet count) followed by ENCAPSULATED_DATA packets of 253
bytes. PNG keeps a 50 x 50 frame to ~4 kB (about 16 packets)."""

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


def decode_png(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def frame_messages(mav: mavlink.MAVLink, frame: np.ndarray) -> list[mavlink.MAVLink_message]:
    data = encode_png(frame)
    packets = -(-len(data) // PAYLOAD)
    h, w = frame.shape[:2]
    msgs: list[mavlink.MAVLink_message] = [
        mav.data_transmission_handshake_encode(mavlink.MAVLINK_DATA_STREAM_IMG_PNG, len(data), w, h, packets, PAYLOAD, 0)
    ]
    for i in range(packets):
        chunk = data[i * PAYLOAD : (i + 1) * PAYLOAD]
        msgs.append(mav.encapsulated_data_encode(i, chunk.ljust(PAYLOAD, b"\0")))
    return msgs


class FrameAssembler:
    """The receiving side: feed it messages, get whole frames back."""

    def __init__(self) -> None:
        self.meta = None
        self.parts: dict[int, bytes] = {}

    def feed(self, msg) -> np.ndarray | None:
        kind = msg.get_type()
        if kind == "DATA_TRANSMISSION_HANDSHAKE" and msg.packets > 0:
            self.meta, self.parts = msg, {}
        elif kind == "ENCAPSULATED_DATA" and self.meta is not None:
            self.parts[msg.seqnr] = bytes(msg.data)
            if len(self.parts) == self.meta.packets:
                data = b"".join(self.parts[i] for i in range(self.meta.packets))[: self.meta.size]
                self.meta, self.parts = None, {}
                try:
                    return decode_png(data)
                except OSError:
                    return None
        return None
