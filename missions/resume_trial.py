"""A companion killed mid-search and resumed, for real: our SITL in this process (companion
lockstep, its truth recorded for the score), `uavsearch run` as a subprocess on a UDP
loopback link, SIGKILL at a chosen move, `uavsearch run --resume` after it.

Used by the resume test (tests/missions/test_resume.py) and the resume benchmark
(benchmarks/bench_resume.py, results/resume.md). The SITL stays up across the kill, as a
real vehicle does: whatever its failsafes did meanwhile (hold, return, land) is what the
resumed companion finds.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from missions.fieldfile import FieldSpec, write_field
from sim.gridworld import GridConfig

ON_GROUND = 1  # MAV_LANDED_STATE_ON_GROUND


@dataclass
class Vehicle:
    """The SITL of a trial, the field file the companion reads, and the scorer's truth."""

    sitl: Any
    field_file: Path
    track: list[np.ndarray] = field(default_factory=list)
    started: bool = False
    _stop: threading.Event = field(default_factory=threading.Event)
    _watcher: threading.Thread | None = None

    def start(self) -> None:
        """Start the vehicle, and the scorer's view of its truth (never given to the companion)."""
        self.sitl.start()
        self.started = True

        def watch() -> None:
            while not self._stop.is_set():
                self.track.append(self.sitl.vehicle_cell().copy())
                time.sleep(0.05)

        self._watcher = threading.Thread(target=watch, daemon=True)
        self._watcher.start()

    def stop(self) -> None:
        self._stop.set()
        if self._watcher is not None:
            self._watcher.join()
        if self.started:
            self.sitl.stop()

    @property
    def landed_disarmed(self) -> bool:
        s = self.sitl.model.state
        return not s.armed and s.landed


@contextmanager
def vehicle(tmp: Path, seed: int, base_port: int, grid: GridConfig | None = None,
            speedup: float = 10.0) -> Iterator[Vehicle]:
    """Our SITL on ports base_port .. base_port + 3 (vehicle API, companion, GCS pair), with
    companion lockstep, and its field file (the companion at udpin:127.0.0.1:base_port + 1).
    Not started: `Vehicle.start` once the companion listens (`companion_up`), so the flight's
    schedule does not depend on how long the companion took to load (as missions.flight
    starts its link first): a seed then flies the same search every time."""
    from missions.flight import _truth_sitl
    from sim.mavlink import SitlConfig

    grid = grid or GridConfig()
    cfg = SitlConfig(speedup=speedup, camera=True, grid=grid, episode_seed=seed, seed=seed, companion_lockstep=True,
                     api_local_port=base_port, api_remote_port=base_port + 1, gcs_local_port=base_port + 2,
                     gcs_remote_port=base_port + 3, bind="127.0.0.1")
    sitl = _truth_sitl(cfg)
    field_file = tmp / "field.json"
    write_field(field_file, FieldSpec(sitl.field_origin, grid, 2.0, f"udpin:127.0.0.1:{base_port + 1}", None,
                                      cfg.physics, cfg.field_edge), seed)
    v = Vehicle(sitl, field_file)
    try:
        yield v
    finally:
        v.stop()


def start_companion(v: Vehicle, *args: str, timeout: float = 120.0) -> tuple[subprocess.Popen, list[str]]:
    """`uavsearch run ARGS`, and the vehicle started once it listens (its "connecting to"
    line). Returns the process and the lines it printed up to then."""
    proc = companion(*args)
    lines = read_until(proc, "connecting to", timeout)
    if not v.started:
        v.start()
    return proc, lines


def read_until(proc: subprocess.Popen, text: str, timeout: float) -> list[str]:
    """Lines of proc's output up to and including the first holding `text` (or its end)."""
    lines: list[str] = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        line = proc.stdout.readline()  # type: ignore[union-attr]
        if not line:
            break
        lines.append(line)
        if text in line:
            break
    return lines


def companion(*args: str) -> subprocess.Popen:
    """`uavsearch run ARGS` as its own process, stdout and stderr merged, line-buffered."""
    root = str(Path(__file__).resolve().parent.parent)  # this checkout's packages, whatever is installed
    path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": path}
    return subprocess.Popen([sys.executable, "-m", "missions", "run", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, bufsize=1, env=env)


def kill_at_move(proc: subprocess.Popen, move: int, delay_s: float = 0.0, timeout: float = 300.0) -> str:
    """SIGKILL the companion delay_s after it reports decision `move` (its progress line), or
    when it ends first. Returns what it printed."""
    lines = read_until(proc, f": move {move}/", timeout)
    if lines and f": move {move}/" in lines[-1]:
        time.sleep(delay_s)
        proc.send_signal(signal.SIGKILL)
    rest, _ = proc.communicate(timeout=30)
    return "".join(lines) + (rest or "")


def truly_found(v: Vehicle) -> int:
    """Targets the vehicle truly flew within half a cell of (static targets)."""
    targets = v.sitl.episode.targets[0]
    tr = np.array(v.track) if v.track else np.zeros((0, 2))
    if not len(tr):
        return 0
    near = np.max(np.abs(tr[:, None, :] - targets[None]), axis=2) < 0.5
    return int(near.any(axis=0).sum())


def search_log(out: Path) -> dict[str, Any]:
    return json.loads((out / "search_log.json").read_text())


def wait_until(pred, timeout: float, step: float = 0.1) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(step)
    return bool(pred())
