"""Many SITL vehicles in one process and one thread (`uavsearch sitl --count N`).

Each vehicle is a full `Sitl` (its own MAVLink system id, PX4 SITL's ports for its instance,
GPS, field and camera, tlog), but the airframes are members of one fleet (sim/vehicle/fleet.py):
one physics step and one vectorised controller for all, then every vehicle's MAVLink tick. One
loop paces the lot at the speed-up and answers any vehicle's messages as they arrive.
- Quiet ticks (quiet.py): a vehicle whose tick would change nothing but its battery (most
  ticks of a hovering or cruising vehicle) is stepped with numpy over the fleet; the others,
  and every vehicle that received something, take the full tick.
- Telemetry streams are each vehicle's own, paced as a lone vehicle paces them, but built for
  all vehicles at once (fleet_telemetry.py); the messages a vehicle streams in one tick go out
  as one datagram per link (several MAVLink packets back to back, as ArduPilot SITL sends them).
Both give the same bytes and the same flight as every vehicle ticked in full and building its
own telemetry (`quiet_ticks=False, vector_telemetry=False`; tests/sim/mavlink/test_quiet.py).
"""

from __future__ import annotations

import logging
import select
import threading
import time
import traceback
from collections.abc import Sequence

from sim.vehicle.fleet import KinematicFleet, QuadrotorFleet

from .fleet_telemetry import FleetTelemetry
from .quiet import QuietFleet
from .runner import BackgroundRunner, pace
from .sitl import TICK_S, Sitl, SitlConfig

log = logging.getLogger(__name__)


class SitlFleet(BackgroundRunner):
    """Build with one SitlConfig per vehicle (same physics and speed-up), then `start()` or
    `run()`; `stop()` closes every vehicle."""

    def __init__(self, cfgs: Sequence[SitlConfig], quiet_ticks: bool = True, vector_telemetry: bool = True) -> None:
        """quiet_ticks False: every vehicle takes its full tick every tick (quiet.py);
        vector_telemetry False: each vehicle builds its own telemetry (fleet_telemetry.py)."""
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
        self.errors: list[str] = []
        arrays = isinstance(self.world, (KinematicFleet, QuadrotorFleet))  # its states read its arrays (ArrayState)
        self.telemetry = FleetTelemetry(self.errors, self.world if arrays else None)
        for i, s in enumerate(self.sitls):
            s.vehicle.fleet_index = i
        for s in self.sitls:  # each tick's telemetry built over the fleet, one datagram per link a vehicle
            if vector_telemetry and s.vehicle.dialect.fleet_vectorised:
                s.vehicle.stream_sink = self.telemetry.sink
            else:  # built and sent in each vehicle's tick, still one datagram per link
                s.vehicle.batch_streams = True
        self._owner = {link.sock: i for i, s in enumerate(self.sitls) for link in s.vehicle.links}
        self._streaming = [s for s in self.sitls if s.video is not None]
        self._owner_fd = {sock.fileno(): i for sock, i in self._owner.items()}
        self.quiet = QuietFleet(self.sitls, quiet_ticks, world=self.world)  # ticks changing only the battery
        self._poller = select.epoll() if hasattr(select, "epoll") else select.poll()
        for fd in self._owner_fd:
            self._poller.register(fd, select.POLLIN)
        self.t = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __len__(self) -> int:
        return len(self.sitls)

    def __getitem__(self, i: int) -> Sitl:
        return self.sitls[i]

    def wake(self, i: int) -> None:
        """Give vehicle i a full tick next (after changing it other than over MAVLink)."""
        self.quiet.wake(i)

    def step(self) -> None:
        w = self.world
        w.step(TICK_S)
        self.t += TICK_S
        # one poll over every vehicle's sockets, not two failing recvfrom calls per vehicle
        for i in {self._owner_fd[fd] for fd, _ in self._poller.poll(0)}:
            self._serve_one(i)
        self.quiet.tick(self.t, w.positions_ned, w.armed, w.landed)
        self.telemetry.flush()
        for sitl in self._streaming:  # camera video streams (sitl --video-port), quiet or not
            sitl._stream_video(self.t)

    def _serve_one(self, i: int) -> None:
        self.sitls[i].vehicle.service()
        self.quiet.wake(i)  # what arrived may have changed it: a full tick next

    def run(self, duration: float | None = None) -> None:
        self.quiet.awake[:] = True  # whatever was done to the vehicles between runs is seen
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
        for i in {self._owner[sock] for sock in ready}:
            self._serve_one(i)

    def _thread_name(self) -> str:
        return f"sitl-fleet-{len(self)}"

    def _close(self) -> None:
        if hasattr(self, "_poller") and hasattr(self._poller, "close"):
            self._poller.close()
        for s in self.sitls:
            s.stop()
        self.world.close()
