"""Telemetry logs in MAVProxy's .tlog format: each packet prefixed by its receive/send time as
an 8-byte big-endian count of microseconds since the Unix epoch. Written to NAME.part and
renamed to NAME on close, so a log is either complete or visibly partial."""

from __future__ import annotations

import os
import struct
import time
from pathlib import Path


class TlogWriter:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.part = self.path.with_name(self.path.name + ".part")
        self.f = open(self.part, "wb")  # noqa: SIM115 - closed in close()

    def write(self, packet: bytes, _outgoing: bool = True) -> None:
        if self.f.closed:
            return
        self.f.write(struct.pack(">Q", int(time.time() * 1e6)) + packet)

    def close(self) -> None:
        if not self.f.closed:
            self.f.flush()
            os.fsync(self.f.fileno())
            self.f.close()
            os.replace(self.part, self.path)
