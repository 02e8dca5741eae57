"""A flight's vehicle when a real autopilot flies our world (sim.bridges): the world with its
camera component, on an instance no other flight on this machine holds, seen by the scorer
through the same few names as our own SITL (`t`, `target_cells`, `vehicle_cell`, `truth`,
`height`, `episode`, `field_origin`), so missions.flight scores both alike.

Real autopilots take their ports from their instance number (PX4: 0-9 only), so parallel
flights each hold an instance by a lock file for as long as they fly: two flight-table
workers starting at the same instant cannot pick the same one."""

from __future__ import annotations

import fcntl
import os
import socket
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

#: instances a flight may take (PX4 keeps its 14540 + N layout for 0-9; 0 is left to people)
INSTANCES = range(1, 10)


def _udp_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            return False
    return True


@contextmanager
def hold_instance(lock_dir: Path | None = None) -> Iterator[int]:
    """An instance number held (flock) for the block, whose companion and camera ports are free."""
    lock_dir = Path(lock_dir or tempfile.gettempdir())
    for n in INSTANCES:
        f = open(lock_dir / f"uavsearch-autopilot-instance-{n}.lock", "w")  # noqa: SIM115 - held for the block
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        # the companion's and the camera component's ports (sim.bridges.world: 14600 + n is the
        # camera's own, which our SITL's API link takes at instance n + 20: a test flying
        # instance 21 beside this one made the camera's bind fail and the flight time out)
        if not (_udp_free(14540 + n) and _udp_free(14560 + n) and _udp_free(14600 + n)):
            f.close()
            continue
        try:
            f.write(str(os.getpid()))
            f.flush()
            yield n
        finally:
            f.close()
        return
    raise RuntimeError(f"no free autopilot instance in {INSTANCES.start}-{INSTANCES.stop - 1} "
                       "(other flights hold them, or their ports are taken)")


class WorldVehicle:
    """The scorer's view of an AutopilotWorld (never given to the companion)."""

    def __init__(self, world: Any) -> None:
        self.world = world
        self.errors: list[str] = []
        self.lockstep_timeouts = 0
        self.video = None

    @property
    def t(self) -> float:
        return self.world.t

    def target_cells(self, t: float | None = None):
        return self.world.target_cells(t)

    def vehicle_cell(self):
        return self.world.vehicle_cell()

    @property
    def truth(self) -> list:
        return self.world.truth

    @property
    def height(self) -> list:
        return self.world.height

    @property
    def episode(self):
        return self.world.scene.episode

    @property
    def field_origin(self):
        return self.world.scene.field_origin

    def stop(self) -> None:
        self.world.stop()
