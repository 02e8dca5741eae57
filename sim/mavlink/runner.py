"""The simulation loop's life cycle, shared by one SITL vehicle and a fleet: run on a
background thread, stop and close, use as a context manager, and pace simulated time against
the wall clock while answering MAVLink as it arrives."""

from __future__ import annotations

import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Self


class BackgroundRunner:
    """Subclasses set `_stop` (Event) and `_thread` (None) and give run(), _thread_name(),
    _close()."""

    _stop: threading.Event
    _thread: threading.Thread | None

    def run(self, duration: float | None = None) -> None:
        raise NotImplementedError

    def _thread_name(self) -> str:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> Self:
        self._thread = threading.Thread(target=self.run, name=self._thread_name(), daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def pace(wall0: float, t: float, speedup: float, socks: list[socket.socket],
         serve: Callable[[list[socket.socket]], None]) -> None:
    """Wait until simulated time t is due at `speedup`, serving sockets as data arrives rather
    than on the tick, so command latency stays at the network's, not the tick's."""
    while (lag := wall0 + t / speedup - time.monotonic()) > 0:
        ready, _, _ = select.select(socks, [], [], lag)
        if ready:
            serve(ready)
