"""A seeded fault-injecting UDP proxy: a bad radio between a vehicle and its client.

    vehicle (sends to `vehicle_port`) <-> [proxy] <-> client (listens on `client_port`)

The vehicle's link sends to the proxy's vehicle-side socket; the proxy forwards each datagram
to the client from its client-side socket, so the client (a `udpin` listener) answers the
proxy, which forwards back to the vehicle's port. Each direction drops, duplicates, reorders,
delays and corrupts datagrams with the probabilities of its `LinkFaults`, drawn from one seeded
generator per direction, so a failing run can be replayed. Counts per fault are kept for the
reports: a test that claims "20 % loss" can show what was lost.
"""

from __future__ import annotations

import heapq
import itertools
import math
import select
import socket
import threading
import time
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class LinkFaults:
    """What happens to each datagram in one direction (probabilities in [0, 1])."""

    loss: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0  # held back by `reorder_ms` so later datagrams overtake it
    corrupt: float = 0.0  # one random byte flipped (the CRC catches it, or the signature does)
    delay_ms: tuple[float, float] = (0.0, 0.0)  # uniform one-way delay (jitter) for every datagram
    reorder_ms: float = 30.0

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder", "corrupt"):
            p = getattr(self, name)
            if not (math.isfinite(p) and 0.0 <= p <= 1.0):
                raise ValueError(f"LinkFaults.{name} must be a probability in [0, 1] (got {p})")
        lo, hi = self.delay_ms
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo <= hi):
            raise ValueError(f"LinkFaults.delay_ms must be 0 <= lo <= hi (got {self.delay_ms})")
        if not (math.isfinite(self.reorder_ms) and self.reorder_ms >= 0):
            raise ValueError(f"LinkFaults.reorder_ms must be >= 0 (got {self.reorder_ms})")


@dataclass
class FaultCounts:
    forwarded: int = 0
    lost: int = 0
    duplicated: int = 0
    reordered: int = 0
    corrupted: int = 0


@dataclass
class _Direction:
    faults: LinkFaults
    rng: np.random.Generator
    counts: FaultCounts = field(default_factory=FaultCounts)


class FaultProxy:
    """Start with `start()` (a thread), stop with `stop()`; or use as a context manager."""

    def __init__(self, vehicle_port: int, client_port: int, up: LinkFaults | None = None,
                 down: LinkFaults | None = None, seed: int = 0, host: str = "127.0.0.1",
                 vehicle_side_port: int = 0) -> None:
        """`vehicle_port`: where the vehicle listens (0: wherever its first datagram comes from,
        as for ArduPilot's udpclient serial port); `client_port`: where the client listens.
        `down` (vehicle -> client) defaults to `up` (client -> vehicle). Give the vehicle
        `self.vehicle_side_port` as its remote port."""
        self.host, self.vehicle_addr, self.client_addr = host, (host, vehicle_port), (host, client_port)
        up = up or LinkFaults()
        self.up = _Direction(up, np.random.default_rng([seed, 1]))
        self.down = _Direction(down or up, np.random.default_rng([seed, 2]))
        self.vside = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vside.bind((host, vehicle_side_port))
        self.cside = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.cside.bind((host, 0))
        self.vehicle_side_port = self.vside.getsockname()[1]
        self._queue: list[tuple[float, int, bytes, socket.socket, tuple[str, int]]] = []
        self._order = itertools.count()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _schedule(self, d: _Direction, data: bytes, out: socket.socket, dest: tuple[str, int], now: float) -> None:
        f, rng = d.faults, d.rng
        # one draw per fault per datagram, in a fixed order, so runs replay from the seed
        u = rng.random(5)
        lag = rng.uniform(*f.delay_ms) / 1e3 if f.delay_ms[1] > 0 else 0.0
        if u[0] < f.loss:
            d.counts.lost += 1
            return
        if u[1] < f.corrupt and data:
            buf = bytearray(data)
            buf[int(rng.integers(len(buf)))] ^= 1 << int(rng.integers(8))
            data = bytes(buf)
            d.counts.corrupted += 1
        if u[2] < f.reorder:
            lag += f.reorder_ms / 1e3
            d.counts.reordered += 1
        copies = 2 if u[3] < f.duplicate else 1
        d.counts.duplicated += copies - 1
        for k in range(copies):
            heapq.heappush(self._queue, (now + lag + k * 1e-4, next(self._order), data, out, dest))

    def _run(self) -> None:
        socks = [self.vside, self.cside]
        while not self._stop.is_set():
            now = time.monotonic()
            while self._queue and self._queue[0][0] <= now:
                _, _, data, out, dest = heapq.heappop(self._queue)
                try:
                    out.sendto(data, dest)
                except OSError:
                    pass
            wait = min(0.05, max(self._queue[0][0] - now, 0.0)) if self._queue else 0.05
            try:
                ready, _, _ = select.select(socks, [], [], wait)
            except (OSError, ValueError):
                return
            now = time.monotonic()
            for s in ready:
                try:
                    data, addr = s.recvfrom(65535)
                except OSError:
                    continue
                if s is self.vside:  # from the vehicle, on to the client
                    if self.vehicle_addr[1] == 0:
                        self.vehicle_addr = addr
                    self.down.counts.forwarded += 1
                    self._schedule(self.down, data, self.cside, self.client_addr, now)
                else:
                    self.up.counts.forwarded += 1
                    self._schedule(self.up, data, self.vside, self.vehicle_addr, now)

    def cut(self) -> None:
        """From now on nothing gets through, either way: a radio out of range."""
        self.up.faults = self.down.faults = LinkFaults(loss=1.0)

    def start(self) -> FaultProxy:
        self._thread = threading.Thread(target=self._run, name="fault-proxy", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self.vside.close()
        self.cside.close()

    def __enter__(self) -> FaultProxy:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
