"""The companion's own telemetry log (.tlog, MAVProxy's format: each packet prefixed by an
8-byte big-endian count of microseconds since the Unix epoch), of both directions of its link.

pymavlink's `setup_logfile` only logs in the serial reader: a UDP connection never writes a
byte to it, which is why the companion's log used to be empty. This writer is fed by the link
itself (received messages on the receive thread, sent ones through pymavlink's send callback,
from any thread), so it takes a lock. Written to NAME.part and renamed on close, with the
provenance beside it in NAME.json."""

from __future__ import annotations

import os
import struct
import threading
import time
from pathlib import Path
from typing import Any

from provenance import atomic_write_json


class CompanionTlog:
    def __init__(self, path: str | Path, meta: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        self.meta = meta
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.part = self.path.with_name(self.path.name + ".part")
        self._lock = threading.Lock()
        self._f = open(self.part, "wb")  # noqa: SIM115 - closed in close()
        self.packets = 0

    def write(self, packet: bytes) -> None:
        stamp = struct.pack(">Q", int(time.time() * 1e6) & ~3)
        with self._lock:
            if not self._f.closed:
                self._f.write(stamp + packet)
                self.packets += 1

    def write_message(self, msg: Any, *_: Any) -> None:
        """pymavlink message (received, or just packed and sent) -> its bytes on the wire."""
        buf = msg.get_msgbuf()
        if buf:
            self.write(bytes(buf))

    def close(self) -> None:
        with self._lock:
            if self._f.closed:
                return
            self._f.flush()
            os.fsync(self._f.fileno())
            self._f.close()
        os.replace(self.part, self.path)
        if self.meta is not None:
            atomic_write_json(self.path.with_name(self.path.name + ".json"), self.meta)
