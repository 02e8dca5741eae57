"""The policy service: the companion computer's search loop over a real MAVLink link.

Each decision: fuse GPS into the position posterior, spread the visit over the probabilistic
visitation map, ask the vehicle for a camera frame, turn it into the view I, let the policy
pick a move, and fly to the next cell's centre as an OFFBOARD setpoint. It sees only what a
real companion computer would: MAVLink telemetry and frames, the field's corner and size, and
how many targets to find (the paper's known |R|). The truth stays in the simulator.

Decisions run on the vehicle's simulated clock, not on wall-clock races, so a flight given its
seed is reproducible however loaded the machine is: decision k looks at the camera frame
captured at simulated time t_k (asked for ahead, stamped by the vehicle) and at the GPS fixes
stamped up to t_k, and t_{k+1} = t_k + decision_period_s. A leg that has not settled by t_k
(by the vehicle's own telemetry stamped before t_k) slips the schedule by half a period and
is counted; so is a frame asked for after its time had passed. Take-off starts on a lattice
point of the same clock.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable

import numpy as np

from policy.base import Observation, Policy
from sim.gridworld import DELTAS, cell_to_ned, nearest_cell

from .detector import (
    DetectorConfig,
    blob_cells,
    blobs_to_view,
    find_blobs,
    valid_moves,
)
from .estimator import GpsEstimator
from .images import FrameRequester
from .link import LinkError, VehicleLink
from .probmap import ProbabilisticVisitationMap, cell_probabilities
from .search_data import Progress, SearchLog, SearchSpec, save_log
from .telemetry import TelemetryIntake

__all__ = ["PolicyService", "Progress", "SearchLog", "SearchSpec", "save_log"]

log = logging.getLogger(__name__)
DECISION_DEADLINE_S = 5.0  # a decision (map update, policy) that takes longer is a hung loop
FRAME_DEADLINE_S = 20.0  # a frame request, all its resends included

KEEP_FRAMES = 7
#: the launch point (home, the spawn cell's centre) as a position measurement while the vehicle
#: stands on it disarmed: sd of where the vehicle stands on its pad (m)
LAUNCH_SD_M = 0.05
#: simulated seconds of fixes on the launch point registered before arming
LAUNCH_S = 2.0
#: a target seen on a cell's centre measures the camera's true position when its cell is
#: unambiguous: registered only if the nearest lattice point is at least this probable per axis
#: (0.9 picked the wrong lattice point often enough to lock frames a cell off: 20 flights, mean
#: NEES 3.5; 0.97: 1.99, flight/grid 1.21 -> 1.13)
REGISTER_P = 0.97
#: a target counts as found when the camera is truly over it: its centre within this of the
#: nadir on both axes (the scorer's half cell less the detector's error); a target in the
#: believed cell but further off is re-centred on first (at most RECENTRE times a move)
FOUND_M = 0.8
RECENTRE = 2


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
        #: a few camera frames for the operator's report: (move, frame, target channel of I);
        #: the first, those where the detector saw a target (up to KEEP_FRAMES) and the last
        self.kept_frames: list[tuple[int, np.ndarray, list]] = []
        self.last_frame: tuple[int, np.ndarray, list] | None = None
        self.log = SearchLog()
        self.clock = clock
        self._setpoint: np.ndarray | None = None  # local NED (autopilot frame)
        self._stream_stop = threading.Event()
        self._alive_until = float("inf")  # the decision loop's deadline (see _expect)
        self.t_ref: float | None = None  # the schedule's origin on the simulated clock
        self._launch_registered = False
        self._setpoint_lock = threading.Lock()
        #: targets found (or seen again since): (simulated time, receiver-frame north, east)
        self._found_at: list[tuple[float, np.ndarray]] = []
        self.intake = TelemetryIntake(link, spec.origin, self.estimator, spec.arrive_m)

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
                with self._setpoint_lock:  # never resend an old setpoint after a new one
                    self.link.set_position_ned(*self._setpoint)
            time.sleep(0.05)

    # -- the mission ---------------------------------------------------------------------
    def take_off(self, timeout: float = 60.0) -> None:
        link = self.link
        link.wait_heartbeat()
        link.wait_for(lambda: bool(link.telemetry.home) and link.telemetry.gps.get("fix_type", 0) >= 3,
                      timeout, "GPS fix and home position")
        link.wait_for(lambda: self.intake.has_fixes() or self.estimator.initialised, timeout,
                      "a position estimate")
        # the schedule's origin: the lattice point after the first fix this link heard (0 s when
        # the link was up before the vehicle started), not "now", which depends on how long
        # this process took to get going; the start cell comes from the fixes up to it
        period = self.spec.decision_period_s
        self.t_ref = period * math.ceil((self.intake.first_fix_t + 0.5) / period)
        self._register_launch()
        link.arm()
        link.takeoff(link.telemetry.home["alt"] + self.spec.altitude_m)
        link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -(self.spec.altitude_m - 0.4),
                      timeout, f"take-off to {self.spec.altitude_m} m")
        self.intake.wait_sim_time(self.t_ref, timeout)
        if self._launch_registered:
            # the climb is flown on wall-clock command timing (AUTO.TAKEOFF holds the estimate
            # of the instant it was commanded): its fixes would leak centimetres of that timing
            # into the bias the setpoints are shifted by. The registered launch predicted
            # forward stands instead; fixes resume with the first leg.
            self.intake.drop_fixes_until(self.t_ref)
        else:
            self.intake.fuse_until(self.t_ref)
        local = link.telemetry.local
        self._setpoint = np.array([local["n"], local["e"], -self.spec.altitude_m])
        self._expect(DECISION_DEADLINE_S)
        threading.Thread(target=self._stream_setpoints, daemon=True, name="setpoints").start()
        time.sleep(0.3)  # PX4 wants a setpoint stream before OFFBOARD
        link.set_mode("OFFBOARD")

    def _register_launch(self) -> None:
        """Disarmed on the ground, the vehicle stands on home (its launch point, given in the
        field frame by HOME_POSITION): each fix of LAUNCH_S simulated seconds is fused
        with that true position beside it, which averages the receiver's white noise out of
        the GPS bias, so the first cells are flown truly over their centres. (The vehicle waits
        disarmed for this companion, so those seconds are on the ground in every run.)"""
        if not self.spec.register or self.link.telemetry.armed or self.intake.first_fix_t is None:
            return
        # a window on a lattice of the simulated clock after the first fix heard, so a first
        # fix lost or late by a tick registers the same fixes (reproducible)
        t_start = LAUNCH_S * math.ceil((self.intake.first_fix_t + 0.5) / LAUNCH_S)
        t_end = t_start + LAUNCH_S
        # every fix stamped up to t_end has arrived once a later one has
        self.link.wait_for(lambda: self.intake.last_gps_t > t_end + 1e-6, 30.0, f"GPS fixes after {t_end:.1f} s")
        home = self.intake.home_in_field()[:2]
        due = self.intake.take_fixes(t_start, t_end)
        for ft, ned, eph, epv in due:
            self.estimator.update(ft, ned, eph, epv)
            post = self.estimator.posterior()
            err = post.mean_ned[:2] - home
            if float(err @ np.linalg.solve(post.horizontal_cov, err)) > 25.0:  # not on its pad (moved?)
                log.warning("the vehicle is not at home (%.1f m off): launch point not registered", np.hypot(*err))
                return
            self.estimator.observe_position(ft, home, LAUNCH_SD_M)
        self._launch_registered = True
        log.info("launch point registered over %d fixes: GPS bias (n, e, d) %s m", len(due),
                 np.round(self.estimator.bias_ned, 2))

    def camera_height(self) -> float:
        """The camera's height over the (flat) field (see SearchSpec.camera_height)."""
        return self.spec.camera_height()

    def _register_targets(self, t: float, blobs: list, cell: np.ndarray) -> tuple[int, bool]:
        """Static targets stand on cell centres: a target seen at a (GPS-free) offset from the
        camera says where the camera truly is, up to which cell it stands in. Each blob whose
        cell is unambiguous given the posterior (nearest lattice point >= REGISTER_P per axis)
        is fused as a position measurement; so is, whatever the odds, a target placed off the
        field (targets stand on it: the frame is a cell off, so it is put on the nearest cell
        of the field). Returns how many were fused and whether a target fused in the believed
        cell is off the nadir by more than FOUND_M (the vehicle is not truly over it yet)."""
        if not self.spec.register or self.spec.grid.moving or not blobs:
            return 0, False
        g = self.spec.grid
        used, off_centre = 0, False
        cell_m = 2.0
        height = self.camera_height()
        for b in sorted(blobs, key=lambda b: b.sd_m):
            if b.beyond_view(height):
                continue
            post = self.estimator.posterior(t)
            mean = post.mean_ned[:2]
            offset = np.asarray(b.offset_ne(height))
            (cx, cy), = blob_cells([b], mean, height)
            on = (int(np.clip(cx, 0, g.width - 1)), int(np.clip(cy, 0, g.height - 1)))
            # per axis (north, east): is the target placed off the field along it?
            off_field = np.array([on[1] != cy, on[0] != cx])
            z = cell_to_ned(np.array(on)) - offset  # where the camera is, if the target is there
            r = np.abs(z - mean)
            s2 = np.diag(post.horizontal_cov) + b.sd_m**2
            # 1-D odds of the nearest lattice point against the next one along each axis
            ambiguous = (cell_m - r) ** 2 - r**2 < 2.0 * s2 * math.log(REGISTER_P / (1.0 - REGISTER_P))
            # each axis on its own: the lattice is a product of two, the posterior ~isotropic.
            # Off the field along an axis, that axis is forced (whatever the odds); the other
            # is not (it registered a cow placed a column off: seed 3, NEES 27 after)
            axes = tuple(int(i) for i in np.flatnonzero(off_field | ~ambiguous))
            if not axes:
                continue
            if off_field.any():
                self.estimator.doubt_split(cell_m, tuple(int(i) for i in np.flatnonzero(off_field)))
            self.estimator.observe_position(t, z[list(axes)], b.sd_m, axes)
            used += 1
            if on == (int(cell[0]), int(cell[1])) and not b.at_edge and np.abs(offset).max() > FOUND_M:
                off_centre = True
        return used, off_centre

    def _new_targets(self, t: float, blobs: list, cell: np.ndarray) -> tuple[list, list]:
        """The targets in this cell not found before: (those under the camera, those beside it).

        Under the camera: the blob's (GPS-free) offset is within FOUND_M of the nadir on both
        axes, so the vehicle is truly over it, whichever cell the posterior puts it in. Beside
        it: in the believed cell by the posterior, further off (not cut by the frame's edge).
        Found before: the target's position in the autopilot's frame (`_reading_at`: truth +
        GPS bias) is within half a cell of a target found (or seen again) earlier; the two
        readings differ by the bias's drift in between (0.26 m sd over a decision, 0.8 m over
        minutes). Without this a target found a cell off the nadir, or
        seen from the next cell with the posterior a metre off, was found twice (20 flights:
        84 % truly found, every flight believing 5/5)."""
        height = self.camera_height()
        reading = self._reading_at(t)
        mean = self.estimator.posterior(t).mean_ned[:2]
        below, aside = [], []
        for b in blobs:
            if b.beyond_view(height):
                continue
            off = np.asarray(b.offset_ne(height))
            if self._known(t, reading + off):
                continue
            if np.abs(off).max() <= FOUND_M:
                below.append(b)
            elif not b.at_edge and blob_cells([b], mean, height)[0] == (int(cell[0]), int(cell[1])):
                aside.append(b)
        aside.sort(key=lambda b: float(np.abs(b.offset_ne(height)).max()))
        return below, aside

    def _known(self, t: float, at_reading: np.ndarray) -> bool:
        """A target seen at this receiver-frame position is one found before (nearest lattice
        offset between the two is zero); its entry is refreshed (a shorter drift next time)."""
        for i, (_, p) in enumerate(self._found_at):
            if np.all(np.abs(at_reading - p) < 1.0):  # half a 2 m cell
                self._found_at[i] = (t, at_reading)
                return True
        return False

    def _reading_at(self, t: float) -> np.ndarray:
        """Where the autopilot puts the vehicle at simulated time t (local north, east): its
        estimate is the truth plus the GPS bias, smooth (the receiver's white noise is filtered
        out by its inertial fusion), so two readings of one spot a few seconds apart differ by
        the bias's drift only. (The companion's own p + b is noisier: readings of one cow over
        16 s scattered by +-1 m.) Without telemetry then: the companion's p + b."""
        here = self.intake.local_at(t)
        return here if here is not None else self.intake.field_to_local(self.estimator.reading_ne(t)[0])

    def _remember(self, t: float, blobs: list) -> None:
        reading = self._reading_at(t)
        for b in blobs:
            self._found_at.append((t, reading + np.asarray(b.offset_ne(self.camera_height()))))

    def _fly_to(self, cell: np.ndarray) -> np.ndarray:
        """Send the new setpoint at once (the stream repeats it); returns it in local NED. The
        autopilot flies its GPS-fed estimate (truth + bias): the setpoint is shifted by the
        estimated bias so the vehicle is truly over the cell's centre."""
        local = self.intake.field_to_local(cell_to_ned(cell))
        if self.spec.register:
            local = local + self.estimator.bias_ned[:2]
        return self._set_local(local)

    def _set_local(self, local: np.ndarray) -> np.ndarray:
        self.log.setpoints_local.append([round(float(v), 4) for v in local])
        self._expect(DECISION_DEADLINE_S)
        with self._setpoint_lock:
            self._setpoint = np.array([local[0], local[1], -self.spec.altitude_m])
            self.link.set_position_ned(*self._setpoint)
        if self.link.telemetry.mode != "OFFBOARD":  # the autopilot dropped out (e.g. lost setpoints)
            self.link.set_mode("OFFBOARD")
        return local

    def _capture(self, t_k: float, local: np.ndarray, cell: np.ndarray, timeout: float) -> tuple:
        """The frame of decision k: captured at simulated time t_k once the leg has settled,
        else at the next half-period (a slip). Returns (frame or None, its simulated time)."""
        half = self.spec.decision_period_s / 2
        deadline = time.monotonic() + timeout
        self._expect(timeout + FRAME_DEADLINE_S)
        t_at = t_k
        while True:
            frame, t_frame = self.frames.capture(t_at)
            if frame is None:
                return None, max(t_at, self.intake.sim_time_s)
            t_frame = t_at if t_frame is None else t_frame
            if self.intake.settled_at(t_frame, local):
                # a frame captured later than asked (this computer or its link too slow for
                # the speed-up) is flown on, counted: that decision is not reproducible
                self.log.late_frames += int(t_frame > t_at + 0.1)
                return frame, t_frame
            self.log.schedule_slips += 1
            if time.monotonic() > deadline:
                raise LinkError(f"no settled arrival over cell {tuple(int(c) for c in cell)} within {timeout:.0f} s")
            t_at = t_frame + half

    def run(self, timeout_per_move: float = 20.0) -> SearchLog:
        g = self.spec.grid
        max_moves = self.spec.max_moves or g.t_e
        t_start = self.clock()
        post = self.estimator.posterior()
        cell = np.clip(nearest_cell(post.mean_ned[:2]), [0, 0], [g.width - 1, g.height - 1])
        local = self._fly_to(cell)
        # the first decision: take-off and the first leg fit in three periods
        t_k = (self.t_ref if self.t_ref is not None else self.intake.sim_time_s) + 3 * self.spec.decision_period_s
        if self._launch_registered:
            # likewise the climb's tail and the first leg, which starts at the wall-clock instant
            # this loop began: the hover's fixes before the first decision stand for them
            self.intake.skip_fixes_until(t_k - self.spec.decision_period_s / 2)
        self.policy.reset(g, 1, int(self.rng.integers(1 << 30)))
        found = 0
        for move in range(max_moves + 1):
            for attempt in range(RECENTRE + 1):
                frame, t_k = self._capture(t_k, local, cell, timeout_per_move)
                t0 = time.perf_counter()
                self.intake.fuse_until(t_k)
                blobs = find_blobs(frame, self.det) if frame is not None else []
                registered, _ = self._register_targets(t_k, blobs, cell)
                below, aside = self._new_targets(t_k, blobs, cell)
                if below or not aside or attempt == RECENTRE or self.pmap.met[cell[1], cell[0]] > 0.5:
                    break
                # a target not found before in this cell but not under the camera: centre on it
                # (a move relative to where the autopilot is: GPS-free but for 4 s of the
                # bias's drift) and look again; no move of the policy's
                self.log.recentred += 1
                here = self.intake.local_at(t_k)
                if here is None:
                    break
                local = self._set_local(here + np.asarray(aside[0].offset_ne(self.camera_height())))
                t_k = t_k + self.spec.decision_period_s
            height = self.camera_height()
            self.log.blobs.append([[round(v, 3) for v in b.offset_ne(height)] for b in blobs])
            self.log.registered.append(registered)
            post = self.estimator.posterior(t_k)
            exact = self.spec.visit_map == "hard"
            if not exact:  # known to the cell: the crisp visit, as the grid world's
                p_cell = cell_probabilities(post.mean_ned[:2], post.horizontal_cov, g.width, g.height)
                exact = bool(p_cell[cell[1], cell[0]] >= self.spec.exact_above)
            if exact:
                self.pmap.visit(cell_to_ned(cell), np.eye(2) * 1e-6)
            else:
                self.pmap.visit(post.mean_ned[:2], post.horizontal_cov)
            self.log.exact.append(exact)
            self.log.posterior_sd_m.append(float(np.sqrt(post.horizontal_cov.trace() / 2)))
            self.log.cells.append((int(cell[0]), int(cell[1])))
            self.log.times_s.append(float(t_k))
            self.log.posterior_mean_ne.append([float(v) for v in post.mean_ned[:2]])
            self.log.posterior_cov_ne.append(post.horizontal_cov.tolist())
            if frame is None:
                self.log.frames_missing += 1
                view = np.zeros((3, 3, 3), np.uint8)
                view[2, 1, 1] = 1
            else:
                self.log.frames += 1
                # each target lights the one cell its centre is in, the camera taken where the
                # posterior says (GPS-free offsets; a target straddling windows is one target)
                view = blobs_to_view([b for b in blobs if b not in below], post.mean_ned[:2], height, cell,
                                     g.width, g.height)
                view[0, 1, 1] |= bool(below)  # under the camera: in this cell, whatever the posterior
            self.log.seen.append(view[0].astype(int).tolist())
            if frame is not None:
                self.last_frame = (move, frame, view[0].astype(int).tolist())
                if len(self.kept_frames) < KEEP_FRAMES and (move == 0 or view[0].any()):
                    self.kept_frames.append(self.last_frame)
            if below and not self.pmap.met[cell[1], cell[0]] > 0.5:
                # a target under the camera (GPS-free) that is not one found before: found, here
                found += 1
                self._remember(t_k, below)
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
                # the position posterior over cells: belief-state policies (policy/belief) fold the
                # view in as an expectation over it, as in the grid world's GPS evaluation
                position_prob=None if exact else self.pmap.current[None].astype(np.float32),
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
                local = self._fly_to(cell)
            t_k = t_k + self.spec.decision_period_s
        self.log.wall_s = self.clock() - t_start
        return self.log

    def stop_setpoints(self) -> None:
        """Stop streaming OFFBOARD setpoints (before handing the vehicle to an AUTO mode)."""
        self._stream_stop.set()

    def land(self, timeout: float = 60.0) -> None:
        self._stream_stop.set()
        self.link.land()
        self.link.wait_for(lambda: not self.link.telemetry.armed, timeout, "landing and disarm")

