"""The policy service: the companion computer's search loop over a real MAVLink link.

Each decision: fuse GPS into the position posterior, spread the visit over the probabilistic
visitation map, ask the vehicle for a camera frame, turn it into the view I, let the policy
pick a move, and fly to the next cell's centre as an OFFBOARD setpoint. It sees only what a
real companion computer would: MAVLink telemetry and frames, the field's corner and size, and
how many targets to find (the paper's known |R|). The truth stays in the simulator.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from policy.base import Observation, Policy
from sim.gridworld import DELTAS, GridConfig, cell_to_ned, nearest_cell
from sim.gridworld.geodesy import HomePosition

from .detector import DetectorConfig, frame_to_view, valid_moves
from .estimator import GpsEstimator
from .images import FrameRequester
from .link import VehicleLink
from .probmap import ProbabilisticVisitationMap

log = logging.getLogger(__name__)
DECISION_DEADLINE_S = 5.0  # a decision (map update, policy) that takes longer is a hung loop
FRAME_DEADLINE_S = 20.0  # a frame request, all its resends included


@dataclass(frozen=True)
class SearchSpec:
    """What the operator tells the companion computer about the field."""

    origin: HomePosition  # the WGS84 position of cell (0, 0)'s centre
    grid: GridConfig = field(default_factory=GridConfig)
    altitude_m: float = 3.5
    arrive_m: float = 0.25
    max_moves: int | None = None  # default: the grid's t_e


@dataclass
class SearchLog:
    cells: list[tuple[int, int]] = field(default_factory=list)
    believed_found: list[int] = field(default_factory=list)  # move index of each believed find
    posterior_sd_m: list[float] = field(default_factory=list)
    decision_ms: list[float] = field(default_factory=list)
    frames: int = 0
    frames_missing: int = 0
    wall_s: float = 0.0


@dataclass(frozen=True)
class Progress:
    """What the operator sees after each decision (the service's own view, never the truth)."""

    move: int
    max_moves: int
    found: int
    n_targets: int
    cell: tuple[int, int]
    elapsed_s: float
    position_sd_m: float


class PolicyService:
    def __init__(self, link: VehicleLink, policy: Policy, spec: SearchSpec, seed: int = 0,
                 detector: DetectorConfig | None = None, clock=time.monotonic,
                 on_progress: Callable[[Progress], None] | None = None) -> None:
        self.link, self.policy, self.spec = link, policy, spec
        self.on_progress = on_progress
        self.det = detector or DetectorConfig(altitude_m=spec.altitude_m)
        self.rng = np.random.default_rng([seed, 0x5E2])
        self.estimator = GpsEstimator()
        self.pmap = ProbabilisticVisitationMap(spec.grid.width, spec.grid.height)
        self.frames = FrameRequester(link)
        self.log = SearchLog()
        self.clock = clock
        self._setpoint: np.ndarray | None = None  # local NED (autopilot frame)
        self._stream_stop = threading.Event()
        self._alive_until = float("inf")  # the decision loop's deadline (see _expect)
        self._last_gps_t = -1.0
        link.add_handler(self._on_message)

    # -- frames: field NED (origin = cell (0,0)) vs the autopilot's local NED (origin = home) --
    def _home_in_field(self) -> np.ndarray:
        h = self.link.telemetry.home
        return self.spec.origin.geodetic_to_ned(h["lat"], h["lon"], h["alt"])

    def field_to_local(self, ne_field: np.ndarray) -> np.ndarray:
        off = self._home_in_field()
        return np.array([ne_field[0] - off[0], ne_field[1] - off[1]])

    def _on_message(self, msg) -> None:
        if msg.get_type() == "GPS_RAW_INT" and msg.fix_type >= 3 and msg.time_usec * 1e-6 > self._last_gps_t:
            t = msg.time_usec * 1e-6
            self._last_gps_t = t
            ned = self.spec.origin.geodetic_to_ned(msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3)
            eph = msg.h_acc * 1e-3 if msg.h_acc else msg.eph * 1e-2
            epv = msg.v_acc * 1e-3 if msg.v_acc else msg.epv * 1e-2
            self.estimator.update(t, ned, eph, epv)

    def _expect(self, seconds: float) -> None:
        """The decision loop promises its next step within `seconds`; past that it is hung and
        the setpoint stream stops, so the vehicle's offboard-loss failsafe takes over (a
        stream that outlives its decision loop would hold the vehicle in OFFBOARD for ever)."""
        self._alive_until = time.monotonic() + seconds

    def _stream_setpoints(self) -> None:
        starved = False
        while not self._stream_stop.is_set():
            if time.monotonic() > self._alive_until:
                if not starved:
                    log.warning("decision loop silent past its deadline: setpoints stopped, the vehicle's "
                                "offboard-loss failsafe takes over")
                starved = True
            elif self._setpoint is not None:
                starved = False
                self.link.set_position_ned(*self._setpoint)
            time.sleep(0.05)

    # -- the mission ---------------------------------------------------------------------
    def take_off(self, timeout: float = 60.0) -> None:
        link = self.link
        link.wait_heartbeat()
        link.wait_for(lambda: bool(link.telemetry.home) and link.telemetry.gps.get("fix_type", 0) >= 3,
                      timeout, "GPS fix and home position")
        link.wait_for(lambda: self.estimator.initialised, timeout, "a position estimate")
        link.arm()
        link.takeoff(link.telemetry.home["alt"] + self.spec.altitude_m)
        link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -(self.spec.altitude_m - 0.4),
                      timeout, f"take-off to {self.spec.altitude_m} m")
        local = link.telemetry.local
        self._setpoint = np.array([local["n"], local["e"], -self.spec.altitude_m])
        self._expect(DECISION_DEADLINE_S)
        threading.Thread(target=self._stream_setpoints, daemon=True, name="setpoints").start()
        time.sleep(0.3)  # PX4 wants a setpoint stream before OFFBOARD
        link.set_mode("OFFBOARD")

    def _fly_to(self, cell: np.ndarray, timeout: float) -> None:
        ne = cell_to_ned(cell)
        local = self.field_to_local(ne)
        self._setpoint = np.array([local[0], local[1], -self.spec.altitude_m])
        self._expect(timeout + DECISION_DEADLINE_S)

        if self.link.telemetry.mode != "OFFBOARD":  # the autopilot dropped out (e.g. lost setpoints)
            self.link.set_mode("OFFBOARD")

        def arrived() -> bool:
            # settled on the setpoint by the autopilot's own estimate, so the camera looks
            # straight down on the cell (up to the GPS error the posterior accounts for)
            tl = self.link.telemetry.local
            if "n" not in tl:
                return False
            off = np.hypot(tl["n"] - local[0], tl["e"] - local[1])
            return bool(off < self.spec.arrive_m and np.hypot(tl["vn"], tl["ve"]) < 0.25)

        self.link.wait_for(arrived, timeout, f"arrival over cell {tuple(cell)}")

    def run(self, timeout_per_move: float = 20.0) -> SearchLog:
        g = self.spec.grid
        max_moves = self.spec.max_moves or g.t_e
        t_start = self.clock()
        post = self.estimator.posterior()
        cell = np.clip(nearest_cell(post.mean_ned[:2]), [0, 0], [g.width - 1, g.height - 1])
        self._fly_to(cell, timeout_per_move)
        self.policy.reset(g, 1, int(self.rng.integers(1 << 30)))
        found = 0
        for move in range(max_moves + 1):
            t0 = time.perf_counter()
            post = self.estimator.posterior()
            self.pmap.visit(post.mean_ned[:2], post.horizontal_cov)
            self.log.posterior_sd_m.append(float(np.sqrt(post.horizontal_cov.trace() / 2)))
            self.log.cells.append((int(cell[0]), int(cell[1])))
            self._expect(FRAME_DEADLINE_S)
            frame = self.frames.request()
            if frame is None:
                self.log.frames_missing += 1
                view = np.zeros((3, 3, 3), np.uint8)
                view[2, 1, 1] = 1
            else:
                self.log.frames += 1
                view = frame_to_view(frame, cell, g.width, g.height, self.det)
            if view[0, 1, 1] and not self.pmap.met[cell[1], cell[0]] > 0.5:
                found += 1
                self.pmap.mark_target()
                self.log.believed_found.append(move)
                view[0, 1, 1] = 1
            if self.on_progress is not None:
                self.on_progress(Progress(move, max_moves, found, g.n_targets, (int(cell[0]), int(cell[1])),
                                          self.clock() - t_start, self.log.posterior_sd_m[-1]))
            if found >= g.n_targets or move == max_moves:
                break
            obs = Observation(
                views=view[None], maps=self.pmap.policy_map(g.map_variant)[None],
                positions=cell[None].astype(np.int64), valid=valid_moves(cell, g.width, g.height, g.n_actions)[None],
                t=np.array([move]), active=np.array([True]),
            )
            self._expect(DECISION_DEADLINE_S)
            a = int(self.policy.act(obs)[0])
            stay = False
            if not obs.valid[0, a]:
                if getattr(self.policy, "off_map", "random") == "stay":
                    stay = True  # a wall bump leaves it in place, as in the world it learned in (DRQN)
                else:  # off the map: a random valid move instead (Section V-A)
                    a = int(self.rng.choice(np.flatnonzero(obs.valid[0])))
            self.log.decision_ms.append(1e3 * (time.perf_counter() - t0))
            if not stay:
                cell = cell + DELTAS[a]
                self._fly_to(cell, timeout_per_move)
        self.log.wall_s = self.clock() - t_start
        return self.log

    def stop_setpoints(self) -> None:
        """Stop streaming OFFBOARD setpoints (before handing the vehicle to an AUTO mode)."""
        self._stream_stop.set()

    def land(self, timeout: float = 60.0) -> None:
        self._stream_stop.set()
        self.link.land()
        self.link.wait_for(lambda: not self.link.telemetry.armed, timeout, "landing and disarm")


def save_log(log: SearchLog, path: Path, **extra: Any) -> None:
    """The search log, plus anything the caller adds (how the flight ended, provenance)."""
    from dataclasses import asdict

    from provenance import atomic_write_json

    atomic_write_json(path, {**asdict(log), **extra})
