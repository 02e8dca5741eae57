"""The operator's three processes for the flight tests: a `uavsearch sitl` subprocess, a
`uavsearch run` subprocess and a plain pymavlink ground station watching the vehicle on its GCS
port (nothing of ours in the station: only mavutil)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink import mavutil

M = mavutil.mavlink


@dataclass
class Seen:
    armed: list[bool] = field(default_factory=list)
    max_alt_m: float = 0.0
    alt_m: float = 0.0
    landed_state: int = 0
    modes: list[int] = field(default_factory=list)


class GroundStation:
    """Listens on the vehicle's GCS port and keeps what an operator would look at."""

    def __init__(self, port: int) -> None:
        self.c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255, source_component=190)
        self.seen = Seen()
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._loop, daemon=True)
        self._t.start()

    def _loop(self) -> None:
        s = self.seen
        while not self._stop.is_set():
            m = self.c.recv_match(blocking=True, timeout=0.2)
            if m is None:
                continue
            kind = m.get_type()
            # the autopilot's heartbeat (the camera component's, MAV_AUTOPILOT_INVALID, says nothing of the flight)
            if kind == "HEARTBEAT" and m.type != M.MAV_TYPE_GCS and m.autopilot != M.MAV_AUTOPILOT_INVALID:
                armed = bool(m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
                if not s.armed or s.armed[-1] != armed:
                    s.armed.append(armed)
                if not s.modes or s.modes[-1] != m.custom_mode:
                    s.modes.append(m.custom_mode)
            elif kind == "GLOBAL_POSITION_INT":
                s.alt_m = m.relative_alt * 1e-3
                s.max_alt_m = max(s.max_alt_m, s.alt_m)
            elif kind == "EXTENDED_SYS_STATE":
                s.landed_state = m.landed_state

    @property
    def armed_now(self) -> bool:
        return bool(self.seen.armed and self.seen.armed[-1])

    def close(self) -> None:
        self._stop.set()
        self._t.join(timeout=2)
        self.c.close()


class Lines:
    """A subprocess's stdout, read on a thread so the test can wait for a line."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._t.start()

    def _read(self, proc: subprocess.Popen) -> None:
        for line in proc.stdout:  # type: ignore[union-attr]
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, text: str, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if any(text in ln for ln in self.lines):
                return True
            time.sleep(0.1)
        return False

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


def until(pred, timeout: float, poll_s: float = 0.1) -> bool:
    """Poll pred until it holds or timeout seconds pass; its last answer."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(poll_s)
    return pred()


def stop_process(proc: subprocess.Popen, grace_s: float = 20.0) -> None:
    """SIGTERM, then SIGKILL after grace_s: a process the test started is gone afterwards."""
    if proc.poll() is None:
        proc.terminate()
    try:
        proc.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=10)


def uavsearch(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "missions", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, bufsize=1)


@contextmanager
def sitl_process(tmp: Path, instance: int, *args: str) -> Iterator[tuple[Path, GroundStation, Lines]]:
    """A `uavsearch sitl` on its own GCS port (14550 + instance), its field file, and a ground
    station on that port; everything stopped (SIGTERM) afterwards."""
    gcs = GroundStation(14550 + instance)
    field_file = tmp / "field.json"
    proc = uavsearch("sitl", "--instance", str(instance), "--gcs-port-per-instance", "--field-out",
                     str(field_file), *args)
    out = Lines(proc)
    try:
        assert out.wait_for("uavsearch run --field", 60), out.text
        end = time.monotonic() + 30
        while not gcs.seen.armed and time.monotonic() < end:  # the first heartbeat: it is up
            time.sleep(0.1)
        assert gcs.seen.armed == [False], "the ground station hears a disarmed vehicle"
        yield field_file, gcs, out
    finally:
        stop_process(proc, 15)
        gcs.close()
