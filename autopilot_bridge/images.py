"""Receiving camera frames over MAVLink's image transmission protocol: a
DATA_TRANSMISSION_HANDSHAKE announces a PNG of `size` bytes in `packets` ENCAPSULATED_DATA
packets; when all have arrived the PNG is decoded.

Over a lossy radio a 17-packet frame arrives whole only 0.8^17 = 2 % of the time at 20 %
loss, and the protocol has no way to ask for one packet again. So the vehicle resends the
same picture when asked again while it has not moved (sim/mavlink/streams.py), and the
assembler here keeps the chunks of an unfinished frame across handshakes that announce the
same picture (same size, packet count and dimensions), filling in what was missed. Chunks may
come in any order, twice, or out of range; a frame that does not decode (chunks of two
different pictures) is dropped and asked for again.

The simulated vehicle stamps each PNG with its capture time (tEXt "sim_time_s"); the
requester can ask for a frame captured at a given simulated time and wait for exactly that one,
so a decision sees the picture of its own instant, however late the link delivers it.
"""

from __future__ import annotations

import io
import threading

import numpy as np
from PIL import Image

from .link import VehicleLink, mavlink

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


class FrameRequester:
    """Asks the vehicle for a camera frame and collects it on the link's receive thread; asks
    again (the vehicle resends the same picture) until it is whole or the tries run out."""

    def __init__(self, link: VehicleLink) -> None:
        self.link, self.asm = link, FrameAssembler()
        self.latest: np.ndarray | None = None
        self.latest_time_s: float | None = None
        self.event = threading.Event()
        self._cv = threading.Condition()
        self.requests = 0
        link.add_handler(self._on_message)

    def _on_message(self, msg) -> None:
        if msg.get_type() in ("DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA"):
            frame = self.asm.feed(msg)
            if frame is not None:
                with self._cv:
                    self.latest, self.latest_time_s = frame, self.asm.last_time_s
                    self.event.set()
                    self._cv.notify_all()

    def ask(self, at_s: float) -> None:
        """Ask for a frame captured at simulated time at_s (ahead of time; REQUEST_MESSAGE's
        param 2, which the simulated vehicle reads as the capture time)."""
        self.requests += 1
        self.link.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE,
                          float(at_s))

    def wait(self, at_s: float, timeout: float) -> tuple[np.ndarray | None, float | None]:
        """The first frame captured at or after at_s (an unstamped frame is taken as it comes)."""
        def ok() -> bool:
            return self.latest is not None and (self.latest_time_s is None or self.latest_time_s >= at_s - 1e-3)

        with self._cv:
            if self._cv.wait_for(ok, timeout):
                return self.latest, self.latest_time_s
        return None, None

    def capture(self, at_s: float, timeout: float = 1.5, tries: int = 8) -> tuple[np.ndarray | None, float | None]:
        """The frame captured at simulated time at_s, asking again (the vehicle resends the
        same stamped picture) until it is whole or the tries run out; (None, None) then."""
        for _ in range(tries):
            self.ask(at_s)
            frame, t = self.wait(at_s, timeout)
            if frame is not None:
                return frame, t
        return None, None

    def request(self, timeout: float = 1.5, tries: int = 8) -> np.ndarray | None:
        """A fresh frame, or None when `tries` requests of `timeout` seconds each brought none."""
        self.event.clear()
        for _ in range(tries):
            self.requests += 1
            self.link.request_message(mavlink.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE)
            if self.event.wait(timeout):
                return self.latest
        return None
