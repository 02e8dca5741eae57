"""Telemetry logs in MAVProxy's .tlog format: each packet prefixed by its receive/send time as
an 8-byte big-endian count of microseconds since the Unix epoch. Written to NAME.part and
renamed to NAME on close, so a log is either complete or visibly partial. The format has no
room for provenance, so it goes beside the log, in NAME.json (config, seed, git revision)."""

from __future__ import annotations

import os
import struct
import time
from pathlib import Path
from typing import Any

from provenance import atomic_write_json


class TlogWriter:
    def __init__(self, path: str | Path, meta: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        self.meta = meta
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
            if self.meta is not None:
                atomic_write_json(self.path.with_name(self.path.name + ".json"), self.meta)
