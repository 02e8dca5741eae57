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

This module is the decision loop; the service owns one part per concern, each in its own
module: `telemetry` (GPS fixes and the autopilot's estimate off the link, read by their
stamps), `registration` (the launch point and targets as GPS-free position measurements),
`found` (the memory of the targets found, and which blobs of a frame they are), `pilot`
(take-off, the setpoint stream and its deadline, landing) and `search_data` (the spec, log and
progress it exchanges with the operator; re-exported here, so `from autopilot_bridge.service.policy_service
import SearchSpec` keeps working).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from policy.base import Observation, Policy
from sim.gridworld import DELTAS, LEVEL_DELTAS, cell_to_ned, nearest_cell

from ..camera import FrameSource, MavlinkCamera
from ..detection.detector import NOFLY_RGB, DetectorConfig, find_blobs
from ..detection.found import FoundTargets
from ..detection.view import (
    blobs_to_view,
    far_likelihood,
    level_valid_moves,
    level_view,
    show_beside,
    show_cells,
    valid_moves,
)
from ..link.connection import LinkError, VehicleLink
from ..localisation.edges import find_edges
from ..localisation.estimator import GpsEstimator
from ..localisation.registration import Registration
from ..localisation.telemetry import READING_SD_M, TelemetryIntake
from .field_area import field_map_valid, field_view_blocked
from .height import FlownHeight
from .pilot import DECISION_DEADLINE_S, FRAME_DEADLINE_S, Pilot
from .probmap import ProbabilisticVisitationMap, cell_probabilities
from .search_data import Progress, SearchLog, SearchSpec, save_log

__all__ = ["PolicyService", "Progress", "SearchLog", "SearchSpec", "save_log"]

KEEP_FRAMES = 7
#: a policy's action meaning "hold this cell" (a fleet's vehicle whose move the separation
#: check refused, autopilot_bridge.service.fleet): the vehicle stays, as a wall bump under off_map "stay"
HOLD = -1
#: a target in the believed cell but off the nadir by more than found.FOUND_M is
#: re-centred on first, at most RECENTRE times a move
RECENTRE = 2


class PolicyService:
    """The companion's search: owns the estimator, the visitation map, the frame requester and
    the four parts (telemetry intake, found targets, registration, pilot), and runs the
    decision loop."""

    def __init__(self, link: VehicleLink, policy: Policy, spec: SearchSpec, seed: int = 0,
                 detector: DetectorConfig | None = None, clock: Callable[[], float] = time.monotonic,
                 on_progress: Callable[[Progress], None] | None = None, frames: FrameSource | None = None) -> None:
        """frames: the camera source (autopilot_bridge.camera.open_source); None, the MAVLink
        camera component on the vehicle's link."""
        self.link, self.policy, self.spec = link, policy, spec
        self.on_progress = on_progress
        self.det = detector or DetectorConfig(altitude_m=spec.altitude_m,
                                              ground_rgb=NOFLY_RGB if spec.area is not None else ())
        self.seed = seed
        self.rng = np.random.default_rng([seed, 0x5E2])
        self.estimator = GpsEstimator()
        self.pmap = ProbabilisticVisitationMap(spec.grid.width, spec.grid.height)
        self.frames: FrameSource = frames if frames is not None else MavlinkCamera(link)
        #: a few camera frames for the operator's report: (move, frame, target channel of I);
        #: the first, those where the detector saw a target (up to KEEP_FRAMES) and the last
        self.kept_frames: list[tuple[int, np.ndarray, list]] = []
        self.last_frame: tuple[int, np.ndarray, list] | None = None
        self.log = SearchLog()
        self.clock = clock
        self.intake = TelemetryIntake(link, spec.origin, self.estimator, spec.arrive_m,
                                      frame=spec.area.frame if spec.area is not None else None)
        self.found = FoundTargets(spec, self.estimator, self.intake)
        self.registration = Registration(link, spec, self.estimator, self.intake, self.found)
        self.pilot = Pilot(link, spec, self.estimator, self.intake, self.registration, self.log, self.frames)
        #: the altitude level flown and the camera's height as flown (autopilot_bridge.service.height);
        #: with levels the parts that read blobs take the height flown, not the commanded one
        self.height = FlownHeight(spec, self.intake)
        if spec.grid.levels > 1:
            self.found.camera_height = self.registration.camera_height = lambda: self.height.camera_m
        #: called after each decision with (next move, its cell, its simulated time): the
        #: journal a restarted companion resumes from (autopilot_bridge.service.journal); None: none
        self.journal: Callable[[int, np.ndarray, float], None] | None = None

    # -- the mission ---------------------------------------------------------------------
    def take_off(self, timeout: float = 60.0) -> None:
        """Register the launch point, climb and start the setpoint stream (see Pilot.take_off)."""
        self.pilot.take_off(timeout)

    def _capture(self, t_k: float, local: np.ndarray, cell: np.ndarray,
                 timeout: float) -> tuple[np.ndarray | None, float]:
        """The frame of decision k: captured at simulated time t_k once the leg has settled,
        else at the next half-period (a slip). Returns (frame or None, its simulated time)."""
        half = self.spec.decision_period_s / 2
        deadline = time.monotonic() + timeout
        self.pilot.expect(timeout + FRAME_DEADLINE_S)
        t_at = t_k
        while True:
            frame, t_frame = self.frames.capture(t_at)
            if frame is None:
                return None, max(t_at, self.intake.sim_time_s)
            t_frame = t_at if t_frame is None else t_frame
            if self.intake.settled_at(t_frame, local) and (
                    self.height.levels == 1 or self.intake.height_settled_at(t_frame, self.pilot.search_d)):
                # a frame captured later than asked (this computer or its link too slow for
                # the speed-up) is flown on, counted: that decision is not reproducible
                self.log.late_frames += int(t_frame > t_at + 0.1)
                return frame, t_frame
            self.log.schedule_slips += 1
            if time.monotonic() > deadline:
                raise LinkError(f"no settled arrival over cell {tuple(int(c) for c in cell)} within {timeout:.0f} s")
            t_at = t_frame + half

    def run(self, timeout_per_move: float = 20.0,
            resume: tuple[int, np.ndarray, float] | None = None) -> SearchLog:
        """The search. resume: (move, cell, t_k) to go on from, with this service's state
        restored from a journal and the vehicle in the air (autopilot_bridge.service.resume)."""
        g = self.spec.grid
        max_moves = self.spec.max_moves or g.t_e
        t_start = self.clock()
        if resume is not None:
            first, cell, t_k = resume
            local = self.pilot.fly_to(cell)
        else:
            first = 0
            post = self.estimator.posterior()
            cell = np.clip(nearest_cell(post.mean_ned[:2]), [0, 0], [g.width - 1, g.height - 1])
            local = self.pilot.fly_to(cell)
            # the first decision: a period after take_off handed over (the first leg and settling)
            t_off = self.pilot.t_offboard if self.pilot.t_offboard is not None else self.intake.sim_time_s
            t_k = t_off + self.spec.decision_period_s
            if self.registration.launch_registered:
                # likewise the climb's tail and the first leg: the hover's fixes before the first
                # decision stand for them
                self.intake.skip_fixes_until(t_k - self.spec.decision_period_s / 2)
            # the policy's own random stream (its tie-breaks) from the flight's seed, as
            # missions.flight.grid_moves seeds the same policy on the same episode in the grid world:
            # the flight/grid yardstick then differs by what flying changes, not by the ties drawn
            # (drawn from this service's stream before: flight seed 16 took 12 moves, the grid
            # world 33, seed 25 36 against 24)
            self.policy.reset(g, 1, self.seed)
        found = len(self.log.believed_found)
        levels = g.levels > 1  # altitude levels (docs/altitude.md): the level is part of each move
        for move in range(first, max_moves + 1):
            lv = self.height.level
            for attempt in range(RECENTRE + 1):
                frame, t_k = self._capture(t_k, local, cell, timeout_per_move)
                t0 = time.perf_counter()
                self.intake.fuse_until(t_k)
                if self.spec.register and self.spec.map_from_reading:
                    self.intake.fuse_reading(t_k, READING_SD_M)
                # the camera's height: the commanded one (one level), else as flown at t_k
                cam_h = self.height.read(t_k, self.pilot.home_d) if levels else self.spec.camera_height()
                blobs = (find_blobs(frame, self.det, cam_h if levels else None) if frame is not None else [])
                # the field's edge first: exact along its axis, it puts the frame right before the
                # targets' lattice is weighed
                if self.spec.area is None:  # the grid's rectangle: its borders are rows and columns
                    edges = find_edges(frame, cam_h, self.det.fov_deg) if frame is not None else []
                    self.registration.register_edges(t_k, edges)
                    if frame is not None:
                        self.registration.register_unseen_edges(t_k, edges, self.det.fov_deg)
                    edge_log = [[e.axis, e.side, round(e.offset_m, 3)] for e in edges]
                else:  # a polygon's edges, at any angle to the grid
                    ring = self.registration.ring_edges(t_k, frame, cam_h, self.det.fov_deg) if frame is not None else []
                    self.registration.register_ring_edges(t_k, ring)
                    edge_log = [[e.edge, round(e.normal_ne[0], 4), round(e.normal_ne[1], 4), round(e.offset_m, 3)]
                                for e in ring]
                # which blobs are targets found before: once, jointly (`FoundTargets.identify`)
                ids = self.found.identify(t_k, blobs)
                known, rest = self.registration.register_known(t_k, blobs, ids)
                registered, _ = self.registration.register_targets(t_k, rest, cell)
                registered += known
                where = self._camera_ne(t_k, self.estimator.posterior(t_k).mean_ned[:2])
                below, aside = self.found.new_targets(t_k, blobs, cell, where, ids)
                if lv > 1:  # a find, and centring on one, at level 1 only (the grid world's rule)
                    below, aside = [], []
                if below or not aside or attempt == RECENTRE or self.pmap.met[cell[1], cell[0]] > 0.5:
                    break
                # a target not found before in this cell but not under the camera: centre on it
                # (a move relative to where the autopilot is: GPS-free but for 4 s of the
                # bias's drift) and look again; no move of the policy's
                self.log.recentred += 1
                here = self.intake.local_at(t_k)
                if here is None:
                    break
                local = self.pilot.set_local(here + np.asarray(aside[0].offset_ne(cam_h)))
                t_k = t_k + self.spec.decision_period_s
            if attempt:
                cell = self._centred_cell(t_k, cell)
            height = cam_h
            self.log.levels_flown.append(lv)
            self.log.camera_height_m.append(round(float(height), 3))
            self.log.blobs.append([[round(v, 3) for v in b.offset_ne(height)] for b in blobs])
            self.log.registered.append(registered)
            self.log.edges.append(edge_log)
            post = self.estimator.posterior(t_k)
            exact = self.spec.visit_map == "hard"
            if not exact:  # known to the cell: the crisp visit, as the grid world's
                p_cell = self._cell_probabilities(t_k)
                exact = bool(p_cell[cell[1], cell[0]] >= self.spec.exact_above)
            if exact:
                self.pmap.visit(cell_to_ned(cell), np.eye(2) * 1e-6)
            else:
                self.pmap.visit_cells(p_cell)
            self.log.exact.append(exact)
            self.log.camera_ne.append([round(float(v), 4) for v in where])
            self.log.posterior_sd_m.append(float(np.sqrt(post.horizontal_cov.trace() / 2)))
            self.log.cells.append((int(cell[0]), int(cell[1])))
            self.log.times_s.append(float(t_k))
            self.log.posterior_mean_ne.append([float(v) for v in post.mean_ned[:2]])
            self.log.posterior_cov_ne.append(post.horizontal_cov.tolist())
            far: list[np.ndarray] = []
            if frame is None:
                self.log.frames_missing += 1
                view = np.zeros((3, 3, 3), np.uint8)
                view[2, 1, 1] = 1
                if levels:  # nothing seen, the level's window's off-map cells as they are
                    view = blobs_to_view([], where, height, cell, g.width, g.height, radius=lv)
            else:
                self.log.frames += 1
                # each target lights the one cell its centre is in, the camera taken where the
                # posterior says (GPS-free offsets; a target straddling windows is one target)
                told = self.found.told_cells(t_k, blobs, ids)
                fresh = [b for b, c in zip(blobs, told, strict=True) if c is None and b not in below and b not in aside]
                view = blobs_to_view(fresh, where, height, cell, g.width, g.height, radius=lv)
                show_cells(view, [c for c in told if c is not None], cell, g.width, g.height)
                if not below:
                    show_beside(view, aside, height, cell, g.width, g.height)
                view[0, lv, lv] |= bool(below)  # under the camera: in this cell, whatever the posterior
                # targets whose near end shows at the frame's edge, one or two cells out: given to
                # the policy as likelihoods over cells (those of found targets left out); with
                # levels the soft-evidence belief reads the level's window only
                far = [] if levels else [
                    far_likelihood(b, where, post.horizontal_cov, cell, height, g.width, g.height)
                    for b, i in zip(blobs, ids, strict=True) if b.beyond_view(height) and i is None]
            if self.spec.area is not None and not levels:  # masked cells read like off-map ones, as in the grid world
                # (with levels the grid world's window shows the grid's bounds only: the mask
                # reaches the policy by the observation's mask and valid moves, `_level_observation`)
                view[1] = field_view_blocked(self.spec.area, cell)
            self.log.seen.append(view[0].astype(int).tolist())
            if frame is not None:
                self.last_frame = (move, frame, view[0].astype(int).tolist())
                if len(self.kept_frames) < KEEP_FRAMES and (move == 0 or view[0].any()):
                    self.kept_frames.append(self.last_frame)
            found_now = 0
            if below and not self.pmap.met[cell[1], cell[0]] > 0.5:
                found_now = 1
                # a target under the camera (GPS-free) that is not one found before: found, here
                found += 1
                self.found.remember(t_k, below, where, cell, post.horizontal_cov)
                self.pmap.mark_target()
                self.log.believed_found.append(move)
                view[0, 1, 1] = 1
            if self.on_progress is not None:
                self.on_progress(Progress(move, max_moves, found, g.n_targets, (int(cell[0]), int(cell[1])),
                                          self.clock() - t_start, self.log.posterior_sd_m[-1]))
            # a fleet's vehicle goes on to the team's round even when it found every target itself:
            # the team counts the finds and says when the search ends (autopilot_bridge.service.fleet)
            if (found >= g.n_targets and not getattr(self.policy, "team_counts_finds", False)) or move == max_moves:
                break
            if levels:
                obs = self._level_observation(view, cell, lv, move, found_now)
            else:
                maps = self.pmap.policy_map(g.map_variant)
                valid = valid_moves(cell, g.width, g.height, g.n_actions)
                if self.spec.area is not None:
                    maps, valid = field_map_valid(self.spec.area, maps, g.map_variant, cell, g.n_actions)
                obs = Observation(
                    views=view[None], maps=maps[None],
                    positions=cell[None].astype(np.int64), valid=valid[None],
                    mask=None if self.spec.area is None else self.spec.area.mask[None],
                    t=np.array([move]), active=np.array([True]),
                    # the position posterior over cells: belief-state policies (policy/belief) fold the
                    # view in as an expectation over it, as in the grid world's GPS evaluation
                    position_prob=None if exact else self.pmap.current[None].astype(np.float32),
                    far_targets=np.stack(far)[None].astype(np.float32) if far else None,
                    # the finds the companion made: exact, whatever the position posterior
                    found_now=np.array([float(found_now)]),
                )
            self.pilot.expect(DECISION_DEADLINE_S)
            a = int(self.policy.act(obs)[0])
            if getattr(self.policy, "finished", False):
                break  # a fleet's search ended with this round (autopilot_bridge.service.fleet: the team found all)
            stay = a == HOLD
            if not stay and not obs.valid[0, a]:
                if getattr(self.policy, "off_map", "random") == "stay":
                    stay = True  # a wall bump leaves it in place, as in the world it learned in (DRQN)
                else:  # off the map: a random valid move instead (Section V-A)
                    a = int(self.rng.choice(np.flatnonzero(obs.valid[0])))
            self.log.decision_ms.append(1e3 * (time.perf_counter() - t0))
            if not stay:
                cell = cell + DELTAS[a]
                if levels and LEVEL_DELTAS[a]:  # climb or descend: the same cell, the next level's height
                    self.height.set_level(lv + int(LEVEL_DELTAS[a]))
                    self.pilot.change_height(self.height.altitude_m())
                local = self.pilot.fly_to(cell)
            t_k = t_k + self.spec.decision_period_s
            if self.journal is not None:
                self.journal(move + 1, cell, t_k)
        self.log.wall_s += self.clock() - t_start
        self.log.late_inputs = self.intake.input_waits_timed_out
        return self.log

    def _level_observation(self, view: np.ndarray, cell: np.ndarray, level: int, move: int,
                           found_now: int) -> Observation:
        """The policy's observation where the field has altitude levels: the level's view laid
        in the (4, W, W) window of the grid world's (`view.level_view`), the level flown, its
        moves (climb, descend), and the believed cell taken as exact (the soft-evidence belief,
        policy.belief.soft, takes exact positions: the registered camera is within a cell)."""
        g = self.spec.grid
        maps, valid = self.pmap.policy_map(g.map_variant), level_valid_moves(cell, level, g)
        area = self.spec.area
        if area is not None:  # a polygon field: masked cells read as visited, a move into one is off the map
            maps, moves = field_map_valid(area, maps, g.map_variant, cell, 4)
            valid[:4] &= moves
        return Observation(
            views=level_view(view, level, g.levels, cell, g.width, g.height)[None],
            maps=maps[None], positions=cell[None].astype(np.int64),
            valid=valid[None], t=np.array([move]), active=np.array([True]),
            mask=None if area is None else area.mask[None],
            found_now=np.array([float(found_now)]), level=np.array([level], np.int64))

    def _centred_cell(self, t: float, cell: np.ndarray) -> np.ndarray:
        """After centring on a target the camera may be over the next cell: the target was
        taken to be in this one with the frame a metre off, and registered on it the posterior
        now says where the camera is. Where it is sure (exact_above) of another cell, the search
        goes on from that one: the view, the map's visit and the find are placed there. Kept on
        the old cell, the view put the targets it showed around the wrong cell, which the
        belief, placing itself by the posterior, read a cell off (flight seed 45: a cow in view
        diagonally was read off the field, and found 40 moves later: 53 moves, grid 29)."""
        p = self._cell_probabilities(t)
        y, x = (int(v) for v in np.unravel_index(int(np.argmax(p)), p.shape))
        if (x, y) != (int(cell[0]), int(cell[1])) and p[y, x] >= self.spec.exact_above:
            self.log.centred_into_next += 1
            return np.array([x, y])
        return cell

    def _cell_probabilities(self, t: float) -> np.ndarray:
        """(h, w) P(the camera is over each cell) at simulated time t: the position posterior's
        components (`GpsEstimator.components`, one per lattice hypothesis), each placed as
        `_camera_ne` places the likeliest, weighed."""
        g = self.spec.grid
        weights, means, covs = self.estimator.components(t)
        bias = self.estimator.component_bias()
        here = self.intake.local_at(t)
        p = np.zeros((g.height, g.width))
        for w, mean, cov, b in zip(weights, means, covs, bias, strict=True):
            p += w * cell_probabilities(self._place(here, mean[:2], b), cov[:2, :2], g.width, g.height)
        return p

    def _camera_ne(self, t: float, posterior_mean: np.ndarray) -> np.ndarray:
        """Where the camera is at simulated time t (field north, east), for the map and the view:
        the autopilot's own estimate then (truth + GPS bias, its receiver noise smoothed by the
        inertial fusion) less the estimated bias, so its error is the bias estimate's alone.
        The companion's posterior mean also carries its fixes' white noise (flight seed 5: 0.57
        and 0.93 m rms per axis against 0.45 and 0.92). Without telemetry at t, or without
        registration (no bias estimated): the posterior mean."""
        return self._place(self.intake.local_at(t), posterior_mean, self.estimator.bias_ned)

    def _place(self, here: np.ndarray | None, posterior_mean: np.ndarray, bias_ned: np.ndarray) -> np.ndarray:
        """The camera (field north, east) from the autopilot's estimate `here` (local; None
        without telemetry) less a bias, or the posterior mean (see `_camera_ne`)."""
        if here is None or not self.spec.register or not self.spec.map_from_reading:
            return posterior_mean
        return here + self.intake.local_origin_in_field()[:2] - bias_ned[:2]

    def stop_setpoints(self) -> None:
        """Stop streaming OFFBOARD setpoints (before handing the vehicle to an AUTO mode)."""
        self.pilot.stop_setpoints()

    def land(self, timeout: float = 60.0) -> None:
        """Stop the setpoint stream, land and wait for the vehicle to disarm."""
        self.pilot.land(timeout)
