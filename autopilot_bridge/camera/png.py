"""Receiving camera frames over MAVLink's image transmission protocol: a
DATA_TRANSMISSION_HANDSHAKE announces a PNG of `size` bytes in `packets` ENCAPSULATED_DATA
packets; when all have arrived the PNG is decoded.

Over a lossy radio a 17-packet frame arrives whole only 0.8^17 = 2 % of the time at 20 %
loss, and the protocol has no way to ask for one packet again. So the camera resends the
same picture when asked again while it has not moved (sim/mavlink/camera_component.py), and
the assembler here keeps the chunks of an unfinished frame across handshakes that announce the
same picture (same size, packet count and dimensions), filling in what was missed. Chunks may
come in any order, twice, or out of range; a frame that does not decode (chunks of two
different pictures) is dropped and asked for again.

The simulated camera stamps each PNG with its capture time (tEXt "sim_time_s"), so a frame
can be matched to the telemetry and GPS fixes of the same instant (the image protocol itself
has no timestamp field).
"""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

TIME_KEY = "sim_time_s"


def decode_png(data: bytes) -> np.ndarray:
    return decode_png_stamped(data)[0]


def decode_png_stamped(data: bytes) -> tuple[np.ndarray, float | None]:
    """The frame and its capture time (None when the sender did not stamp it)."""
    img = Image.open(io.BytesIO(data))
    stamp = img.info.get(TIME_KEY)
    try:
        t = float(stamp) if stamp is not None else None
    except ValueError:
        t = None
    return np.asarray(img.convert("RGB")), t


class FrameAssembler:
    """The receiving side: feed it messages, get whole frames back."""

    def __init__(self) -> None:
        self.meta: tuple[int, int, int, int, int] | None = None  # size, packets, payload, w, h
        self.parts: dict[int, bytes] = {}
        self.bad_frames = 0  # complete but undecodable (chunks of two pictures): dropped
        self.last_time_s: float | None = None  # capture time of the last whole frame

    def feed(self, msg) -> np.ndarray | None:
        kind = msg.get_type()
        if kind == "DATA_TRANSMISSION_HANDSHAKE":
            if msg.packets <= 0 or msg.size <= 0 or msg.payload <= 0:
                return None
            meta = (msg.size, msg.packets, msg.payload, msg.width, msg.height)
            if meta != self.meta:  # another picture: start over; the same one: keep what we have
                self.meta, self.parts = meta, {}
        elif kind == "ENCAPSULATED_DATA" and self.meta is not None:
            size, packets, payload = self.meta[:3]
            if not 0 <= msg.seqnr < packets:
                return None
            self.parts[msg.seqnr] = bytes(msg.data)[:payload]
            if len(self.parts) == packets:
                data = b"".join(self.parts[i] for i in range(packets))[:size]
                self.meta, self.parts = None, {}
                try:
                    frame, self.last_time_s = decode_png_stamped(data)
                    return frame
                except (OSError, ValueError, SyntaxError):
                    self.bad_frames += 1
        return None
