"""Receiving camera frames over MAVLink's image transmission protocol: a
DATA_TRANSMISSION_HANDSHAKE announces a PNG of `size` bytes in `packets` ENCAPSULATED_DATA
packets; when all have arrived the PNG is decoded."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image


def decode_png(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


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
