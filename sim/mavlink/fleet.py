"""Many SITL vehicles in one process and one thread (`uavsearch sitl --count N`).

Each vehicle is a full `Sitl` (its own MAVLink system id, PX4 SITL's ports for its instance,
GPS, field and camera, tlog), but the airframes are members of one fleet (sim/vehicle/fleet.py):
one physics step and one vectorised controller for all, then every vehicle's MAVLink tick. One
loop paces the lot at the speed-up and answers any vehicle's messages as they arrive.
Telemetry streams are each vehicle's own, paced as a lone vehicle paces them; the messages a
vehicle streams in one tick go out as one datagram per link (several MAVLink packets back to
back, as ArduPilot SITL sends them), which roughly halves a 100-vehicle fleet's CPU per tick.
"""

from __future__ import annotations

import logging
import select
import threading
import time
import traceback
from collections.abc import Sequence

from sim.vehicle.fleet import KinematicFleet, QuadrotorFleet

from .runner import BackgroundRunner, pace
from .sitl import TICK_S, Sitl, SitlConfig

log = logging.getLogger(__name__)


class SitlFleet(BackgroundRunner):
    """Build with one SitlConfig per vehicle (same physics and speed-up), then `start()` or
    `run()`; `stop()` closes every vehicle."""

    def __init__(self, cfgs: Sequence[SitlConfig]) -> None:
        if not cfgs:
            raise ValueError("a fleet needs at least one vehicle config")
        kinds = {(c.physics, c.speedup) for c in cfgs}
        if len(kinds) != 1:
            raise ValueError(f"every vehicle of a fleet runs the same physics and speed-up (got {sorted(kinds)})")
        ids = [c.sysid for c in cfgs]
        if len(set(ids)) != len(ids):
            raise ValueError(f"fleet vehicles need distinct MAVLink system ids (got {ids})")
        self.physics, self.speedup = next(iter(kinds))
        n = len(cfgs)
        self.world = QuadrotorFleet(n) if self.physics == "pybullet" else KinematicFleet(n)
        self.sitls: list[Sitl] = []
        try:
            for cfg, member in zip(cfgs, self.world.members, strict=True):
                self.sitls.append(Sitl(cfg, model=member))
        except Exception:
            self._close()
            raise
        for s in self.sitls:  # each tick's telemetry of a vehicle in one datagram per link
            s.vehicle.batch_streams = True
        self._owner = {link.sock: s for s in self.sitls for link in s.vehicle.links}
        self._owner_fd = {sock.fileno(): s for sock, s in self._owner.items()}
        self._poller = select.epoll() if hasattr(select, "epoll") else select.poll()
        for fd in self._owner_fd:
            self._poller.register(fd, select.POLLIN)
        self.t = 0.0
        self.errors: list[str] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __len__(self) -> int:
        return len(self.sitls)

    def __getitem__(self, i: int) -> Sitl:
        return self.sitls[i]

    def step(self) -> None:
        self.world.step(TICK_S)
        self.t += TICK_S
        # one poll over every vehicle's sockets, not two failing recvfrom calls per vehicle
        for s in {self._owner_fd[fd] for fd, _ in self._poller.poll(0)}:
            s.vehicle.service()
        for s in self.sitls:
            s.tick(self.t, serve=False)

    def run(self, duration: float | None = None) -> None:
        wall0 = time.monotonic()
        socks = list(self._owner)
        while not self._stop.is_set() and (duration is None or self.t < duration):
            try:
                self.step()
            except Exception:  # the physics failed: record, keep every vehicle on its link
                self.errors.append(traceback.format_exc())
                log.exception("fleet step failed at t=%.2f", self.t)
                if len(self.errors) > 100:
                    raise
            if self.speedup > 0:
                pace(wall0, self.t, self.speedup, socks, self._serve)

    def _serve(self, ready: list) -> None:
        for s in {self._owner[sock] for sock in ready}:
            s.vehicle.service()

    def _thread_name(self) -> str:
        return f"sitl-fleet-{len(self)}"

    def _close(self) -> None:
        if hasattr(self, "_poller") and hasattr(self._poller, "close"):
            self._poller.close()
        for s in self.sitls:
            s.stop()
        self.world.close()
