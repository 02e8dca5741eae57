"""Position registration: the GPS-free measurements of where the camera truly is, and the
memory of the targets found.

Its own part of the service because GPS alone puts the camera a metre or more off (the
receiver's bias): the launch point (the vehicle standing on home before arming) and targets
standing on cell centres measure the true position, so the bias is registered and the camera
flown truly over each cell; and a target is remembered where the autopilot read it, so one
target seen again from the next cell, or with the posterior a metre off, is not found twice.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from scipy.optimize import linear_sum_assignment

from sim.gridworld import cell_to_ned, nearest_cell

from .detector import FAR_REACH_M, Blob, blob_cells, px_per_m
from .estimator import GpsEstimator
from .link import VehicleLink
from .search_data import SearchSpec
from .telemetry import READING_SD_M, TelemetryIntake

log = logging.getLogger(__name__)

#: the launch point (home, the spawn cell's centre) as a position measurement while the vehicle
#: stands on it disarmed: sd of where the vehicle stands on its pad (m)
LAUNCH_SD_M = 0.05
#: simulated seconds of fixes on the launch point registered before arming
LAUNCH_S = 2.0
#: a found target's cell is recorded (for `register_known`) only where the posterior makes it
#: this probable per axis at the find: a cow found with the camera estimate 1-1.5 m off was
#: recorded a cell off and every re-sighting then locked the frame there (held-out flight seeds
#: 30 and 34: NEES 9)
RECORD_P = 0.9
#: a target counts as found when the camera is truly over it: its centre within this of the
#: nadir on both axes (the scorer's half cell less the detector's error); a target in the
#: believed cell but further off is re-centred on first (at most RECENTRE times a move)
FOUND_M = 0.8
#: a re-sighting of a found target is fused unless it is this many sigmas off the posterior
KNOWN_GATE = 5.0
#: a new target this near the nadir (m, both axes) is beside the camera whichever cell the
#: camera estimate puts it in: with the camera 0.5-0.8 m off its cell either cell is likely,
#: and labelled into the neighbour, the cow's own cell was marked seen-empty with the camera
#: beside it (flight seed 13: 25 moves back and forth next to it). It is centred on first
NEAR_M = 1.3
#: the standard deviation a re-sighting of a found target is fused with (m): the same cow seen
#: again from about the same spot errs the same way (its heading moves the blob's centre), so
#: its sightings are not independent; fused at the detector's 0.3 m, 20 flights had a mean NEES
#: of 3.6
KNOWN_SD_M = 0.5


def lattice_p(r: np.ndarray, s2: np.ndarray, cell_m: float = 2.0) -> np.ndarray:
    """Per axis: the probability of the nearest lattice point (r from the position estimate,
    variance s2 about it) against the next one on either side along that axis. (The next one
    on the far side had been left out as negligible; at the posterior's 0.8-0.9 m sd it is
    not: a cow found with the camera 1.4 m off its believed cell was recorded in that cell at
    0.91 (0.86 with both), every re-sighting then registered the frame a row off, flight seed
    6: NEES 1.2 -> 7.0.)"""
    r = np.asarray(r, dtype=float)
    s2 = np.asarray(s2, dtype=float)
    near = -((cell_m - r) ** 2 - r**2) / (2.0 * s2)
    far = -((cell_m + r) ** 2 - r**2) / (2.0 * s2)
    return 1.0 / (1.0 + np.exp(near) + np.exp(far))


#: the offsets (north, east m) between a cell and its eight neighbours
_NEIGHBOURS = np.array([(dn, de) for dn in (-2.0, 0.0, 2.0) for de in (-2.0, 0.0, 2.0) if dn or de])
#: sd of one blob's offset (m) in matching two sightings (the detector's, inside the frame)
MATCH_SD_M = 0.3
#: sd of a blob's offset across a frame edge that cuts it (m): its centre there is censored
#: (rendered cut cows: 0.2-0.45 m off, up to a metre where little of the cow shows)
CUT_SD_M = 0.6


class Registration:
    """Registers the launch point and targets as position measurements into the estimator,
    and remembers the targets found (in the autopilot's frame)."""

    def __init__(self, link: VehicleLink, spec: SearchSpec, estimator: GpsEstimator,
                 intake: TelemetryIntake) -> None:
        self.link, self.spec, self.estimator, self.intake = link, spec, estimator, intake
        self.launch_registered = False
        #: targets found (or seen again since): (simulated time, receiver-frame north, east)
        self._found_at: list[tuple[float, np.ndarray]] = []
        #: the field cell each found target stands on, by _found_at's index; None where the
        #: camera's estimate and the commanded cell disagreed on it
        self._found_cells: list[tuple[int, int] | None] = []
        #: the cell the policy was told each found target is in (the commanded cell at the find)
        self._told_cells: list[tuple[int, int]] = []

    def register_launch(self) -> None:
        """Disarmed on the ground, the vehicle stands on home (its launch point, given in the
        field frame by HOME_POSITION): each fix of LAUNCH_S simulated seconds is fused
        with that true position beside it, which averages the receiver's white noise out of
        the GPS bias, so the first cells are flown truly over their centres. (The vehicle waits
        disarmed for this companion, so those seconds are on the ground in every run.)"""
        if not self.spec.register or self.link.telemetry.armed or self.intake.first_fix_t is None:
            return
        t_start, t_end = self.launch_window()
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
        if due and self.spec.map_from_reading and self.intake.fuse_reading(t_end, READING_SD_M):
            # the autopilot's estimate on the pad: home plus the bias, without the fixes' white
            # noise, which 2 s of fixes average to 0.19 m sd only (flight seed 43: the bias
            # registered 0.5 m off on both axes, and the first registrations by cows a cell off)
            self.estimator.observe_position(self.estimator.time_s or t_end, home, LAUNCH_SD_M)
        self.launch_registered = True
        log.info("launch point registered over %d fixes: GPS bias (n, e, d) %s m", len(due),
                 np.round(self.estimator.bias_ned, 2))

    def launch_window(self) -> tuple[float, float]:
        """The simulated seconds whose fixes register the launch point: a window on a lattice of
        the simulated clock after the first fix heard, so a first fix lost or late by a tick
        registers the same fixes (reproducible)."""
        first_fix_t = self.intake.first_fix_t if self.intake.first_fix_t is not None else 0.0
        t_start = LAUNCH_S * math.ceil((first_fix_t + 0.5) / LAUNCH_S)
        return t_start, t_start + LAUNCH_S

    def register_targets(self, t: float, blobs: list[Blob], cell: np.ndarray) -> tuple[int, bool]:
        """Static targets stand on cell centres: a target seen at a (GPS-free) offset from the
        camera says where the camera truly is, up to which cell it stands in. Each blob is fused
        along each axis as a mixture over the cell the posterior puts it on and the field's cells
        either side (`GpsEstimator.observe_position_mixture`: the posterior is a Gaussian sum,
        so the odds, not a guess, decide, and a frame a cell off is kept as a hypothesis, not
        averaged in). Before the Gaussian sum only an axis at odds >= 0.8 was fused, and each
        sighting was collapsed to one Gaussian: held-out flights (seeds 40-59) NEES 3.35, now
        1.74. A target placed off the field along an axis forces that axis onto the nearest cell
        of the field (targets stand on it: the frame is a cell off). Returns how many were
        fused and whether a target fused in the believed cell is off the nadir by more than
        FOUND_M (the vehicle is not truly over it yet)."""
        if not self.spec.register or self.spec.grid.moving or not blobs:
            return 0, False
        g = self.spec.grid
        used, off_centre = 0, False
        cell_m = 2.0
        height = self.spec.camera_height()
        for b in sorted(blobs, key=lambda b: b.sd_m):
            if b.beyond_view(height):
                continue
            mean = self.estimator.posterior(t).mean_ned[:2]
            offset = np.asarray(b.offset_ne(height))
            (cx, cy), = blob_cells([b], mean, height)
            on = (int(np.clip(cx, 0, g.width - 1)), int(np.clip(cy, 0, g.height - 1)))
            # per axis (north, east): is the target placed off the field along it?
            off_field = np.array([on[1] != cy, on[0] != cx])
            z = cell_to_ned(np.array(on)) - offset  # where the camera is, if the target is there
            # each axis on its own: the lattice is a product of two. Off the field along an
            # axis, that axis is forced; the other is not (it registered a cow placed a column
            # off: seed 3, NEES 27 after)
            forced = tuple(int(i) for i in np.flatnonzero(off_field))
            # a blob cut by the frame's edge says little of its target's centre across that
            # edge (the target runs on out of the frame by an unknown part of its length): that
            # axis is not registered (flight seed 30: a cow 3.6 m north read at 2.8 m, the
            # north axis registered a row off, NEES 20-45 for the rest of the flight)
            soft = tuple(int(i) for i in np.flatnonzero(~off_field & ~np.array(b.cut_axes)))
            if not forced and not soft:
                continue
            if forced:
                self.estimator.doubt_split(cell_m, forced)
                self.estimator.observe_position(t, z[list(forced)], b.sd_m, forced)
            for i in soft:
                # the cell it stands on along this axis and the field's cells either side of it
                # (north is -y, east is x), as a mixture weighed by the posterior's components
                idx, size = (on[1], g.height) if i == 0 else (on[0], g.width)
                near = [j for j in (idx - 1, idx, idx + 1) if 0 <= j < size]
                centres = np.array([-cell_m * j if i == 0 else cell_m * j for j in near])
                self.estimator.observe_position_mixture(t, i, centres - offset[i], b.sd_m)
            used += 1
            if on == (int(cell[0]), int(cell[1])) and not b.at_edge and np.abs(offset).max() > FOUND_M:
                off_centre = True
        return used, off_centre

    def new_targets(self, t: float, blobs: list[Blob], cell: np.ndarray, camera_ne: np.ndarray,
                    ids: list[int | None] | None = None) -> tuple[list[Blob], list[Blob]]:
        """The targets in this cell not found before: (those under the camera, those beside it).

        Under the camera: the blob's (GPS-free) offset is within FOUND_M of the nadir on both
        axes, so the vehicle is truly over it, whichever cell the posterior puts it in. Beside
        it: in the believed cell, the camera placed at camera_ne (field north, east: the view's
        placement, so a target the view shows in the centre slot is under the camera or beside
        it, never neither), further off, cut by the frame's edge or not (a cut one had been
        left to the view's centre slot, which the policy takes for a find the companion had not
        made: flight seed 78 passed a corner cow 1.8 m off and swept the field for it, 54 moves
        against 24 in the grid world); or, whole in the frame, within NEAR_M of the nadir.
        Found before: the target's position in the autopilot's frame (`reading_at`: truth +
        GPS bias) matches a target found (or seen again) earlier (`match`); the two
        readings differ by the bias's drift in between (0.26 m sd over a decision, 0.8 m over
        minutes). Without this a target found a cell off the nadir, or
        seen from the next cell with the posterior a metre off, was found twice (20 flights:
        84 % truly found, every flight believing 5/5)."""
        height = self.spec.camera_height()
        reading = self.reading_at(t)
        ids = self.identify(t, blobs) if ids is None else ids
        below: list[Blob] = []
        aside: list[Blob] = []
        for b, i in zip(blobs, ids, strict=True):
            if b.beyond_view(height):
                continue
            off = np.asarray(b.offset_ne(height))
            if i is not None:
                self._refresh(i, t, reading + off, b.cut_axes)
                continue
            here = blob_cells([b], camera_ne, height)[0] == (int(cell[0]), int(cell[1]))
            if np.abs(off).max() <= FOUND_M:
                below.append(b)
            elif here or (not b.at_edge and np.abs(off).max() <= NEAR_M):
                aside.append(b)
        aside.sort(key=lambda b: float(np.abs(b.offset_ne(height)).max()))
        return below, aside

    def known(self, t: float, at_reading: np.ndarray, cut: tuple[bool, bool] = (False, False)) -> bool:
        """A target seen at this receiver-frame position is one found before (`match`; cut:
        per axis, is the blob cut by the frame's edge across it). Its entry is refreshed (a
        shorter drift next time) by a blob whole in the frame only: refreshed by cut blobs, whose
        centres are censored, a found cow's entry walked 3 m east over a flight, and 95
        decisions later the cow, seen whole, was not matched and found again (flight seed 103:
        4 of 5 truly found, 5 believed)."""
        i = self.match(at_reading, t, cut)
        if i is not None:
            self._refresh(i, t, at_reading, cut)
        return i is not None

    def _refresh(self, i: int, t: float, at_reading: np.ndarray, cut: tuple[bool, bool]) -> None:
        """Found target i seen again at this reading: its entry refreshed if whole in the frame
        (see `known`)."""
        if not any(cut):
            self._found_at[i] = (t, np.asarray(at_reading, dtype=float))

    def match(self, at_reading: np.ndarray, t: float, cut: tuple[bool, bool] = (False, False)) -> int | None:
        """The found target (its index) seen at this receiver-frame position at simulated time
        t, or None (one sighting alone: `assign`). cut: per axis, is the blob cut by the frame's
        edge across it."""
        return self.assign(t, [np.asarray(at_reading, dtype=float)], [cut])[0]

    def identify(self, t: float, blobs: list[Blob]) -> list[int | None]:
        """Per blob of one frame: the found target (its index) it is, or None (`assign`). A blob
        whose near end only shows at the frame's edge (`Blob.beyond_view`) is placed FAR_REACH_M
        beyond that near end along the cut, as any cut sighting."""
        height = self.spec.camera_height()
        reading = self.reading_at(t)
        at = [reading + self._match_offset(b, height) for b in blobs]
        return self.assign(t, at, [b.cut_axes for b in blobs])

    @staticmethod
    def _match_offset(b: Blob, height: float) -> np.ndarray:
        """The blob's target's offset from the nadir (north, east m) for matching: its centre,
        or for a target beyond the view, FAR_REACH_M past its near end along the cut."""
        off = np.asarray(b.offset_ne(height), dtype=float)
        if b.beyond_view(height):
            near = b.inner_px / px_per_m(height, b.width_px)
            for i, sign in enumerate(b.cut_sides):
                if sign:
                    off[i] = sign * (near + FAR_REACH_M)
        return off

    def assign(self, t: float, at_readings: list[np.ndarray], cuts: list[tuple[bool, bool]]) -> list[int | None]:
        """Which found target (index), if any, each of one frame's sightings is: sighting j, at
        receiver-frame position at_readings[j] at simulated time t, is found target i (found,
        or seen again, at t_i and read at p_i) if the two readings differ by what the GPS bias
        drifts in between (`GpsEstimator.drift_var`) and the two blobs' errors; against it stands
        a new target on a cell next to a found one (the readings a lattice offset apart), a
        priori as likely as a cell holding a target (the field's targets per cell). An axis
        along which a blob is cut by the frame's edge (cuts[j]) has its censored centre's wider
        sd (CUT_SD_M). Before, the offset's nearest lattice point decided alone (half a cell):
        at GPS sigma 2 m the bias drifts 0.55 m per decision and 15 % of the cows were found
        twice.

        Jointly, one to one (the likeliest assignment, `linear_sum_assignment`): two blobs of
        one frame are two targets. Matched one by one, two cows on neighbouring cells, seen
        together 150 s after they were found (the bias drifted 1.3 m meanwhile), were both
        taken for the nearer one's: that cow then registered the frame a cell off and was
        found again (flight seed 78: NEES 18-100 for the flight's last moves)."""
        m, k = len(at_readings), len(self._found_at)
        if m == 0 or k == 0:
            return [None] * m
        g = self.spec.grid
        p_new = min(g.n_targets / (g.width * g.height), 0.5)
        log_prior = math.log(p_new / (1.0 - p_new))
        same = np.empty((m, k))
        new = np.full(m, -np.inf)
        for i, (t_i, p) in enumerate(self._found_at):
            base = self.estimator.drift_var(t - t_i) + 2.0 * MATCH_SD_M**2
            for j, (at, cut) in enumerate(zip(at_readings, cuts, strict=True)):
                v = base + np.where(cut, CUT_SD_M**2, 0.0)
                d = np.asarray(at) - p
                norm = -0.5 * float(np.sum(np.log(v)))
                same[j, i] = norm - 0.5 * float(np.sum(d * d / v))
                other = norm - 0.5 * float(np.sum((d - _NEIGHBOURS) ** 2 / v, axis=1).min()) + log_prior
                new[j] = max(new[j], other)
        # each sighting: one of the found targets, or new (a column of its own)
        score = np.full((m, k + m), -1e9)
        score[:, :k] = same
        score[np.arange(m), k + np.arange(m)] = new
        rows, cols = linear_sum_assignment(-score)
        out: list[int | None] = [None] * m
        for j, c in zip(rows, cols, strict=True):
            out[int(j)] = int(c) if c < k else None
        return out

    def register_known(self, t: float, blobs: list[Blob],
                       ids: list[int | None] | None = None) -> tuple[int, list[Blob]]:
        """A static target found before stands on a known cell, and which one the receiver
        frame says (its reading matches, `match`), whatever the position posterior: a sighting
        of it measures where the camera truly is with no lattice ambiguity. Without this the
        GPS bias went unobserved while the vehicle worked around found targets with a posterior
        too wide to register new sightings (flight seed 18: the camera drifted 1-1.5 m off its
        cells for 30 moves, and the view put a found cow a cell off). A blob cut by the frame's
        edge registers the axis along the cut only. ids: the frame's blobs identified (`identify`;
        worked out here if None). Returns how many were fused and the blobs left for
        `register_targets`: those not found before, and found ones whose cell was not sure."""
        if not self.spec.register or self.spec.grid.moving or not self._found_cells:
            return 0, blobs
        height = self.spec.camera_height()
        ids = self.identify(t, blobs) if ids is None else ids
        used, rest = 0, []
        for b, i in zip(blobs, ids, strict=True):
            off = np.asarray(b.offset_ne(height))
            if b.beyond_view(height):
                i = None
            if i is None:
                rest.append(b)
                continue
            on = self._found_cells[i]
            if on is None:  # its cell unsure: registered by the lattice odds now, as any target
                rest.append(b)
                continue
            # a blob cut by the frame's edge: the axis across the cut is left out (its centre
            # 0.2-0.45 m off), the other kept (rendered cut cows: 0.14 m rms along it, as
            # inside the frame). Cut blobs had been left out whole: flight seed 69 then missed
            # a found cow's east offset while the bias drifted 0.6 m in 4 s
            axes = [i for i, cut in enumerate(b.cut_axes) if not cut]
            if not axes:
                continue
            z = (cell_to_ned(np.array(on)) - off)[axes]
            post = self.estimator.posterior(t)
            r = z - post.mean_ned[axes]
            cov = post.horizontal_cov[np.ix_(axes, axes)] + np.eye(len(axes)) * KNOWN_SD_M**2
            if float(r @ np.linalg.solve(cov, r)) > KNOWN_GATE**2:
                continue  # not where that target could be seen from: a wrong match
            self.estimator.observe_position(t, z, KNOWN_SD_M, tuple(axes))
            used += 1
        return used, rest

    def told_cells(self, t: float, blobs: list[Blob],
                   ids: list[int | None] | None = None) -> list[tuple[int, int] | None]:
        """Per blob: the cell the policy was told it is in where it is a target found before
        (matched by the autopilot's reading, `match`), else None. The view shows a found target
        there, wherever the camera estimate now puts it: the policy's world shows found targets
        where they were found, and one shown a cell away was a target it had not found, which
        it chased back and forth (flight seed 9: 54 moves against 22 in the grid world)."""
        height = self.spec.camera_height()
        ids = self.identify(t, blobs) if ids is None else ids
        return [None if i is None or b.beyond_view(height) else self._told_cells[i]
                for b, i in zip(blobs, ids, strict=True)]

    def reading_at(self, t: float) -> np.ndarray:
        """Where the autopilot puts the vehicle at simulated time t (local north, east): its
        estimate is the truth plus the GPS bias, smooth (the receiver's white noise is filtered
        out by its inertial fusion), so two readings of one spot a few seconds apart differ by
        the bias's drift only. (The companion's own p + b is noisier: readings of one cow over
        16 s scattered by +-1 m.) Without telemetry then: the companion's p + b."""
        here = self.intake.local_at(t)
        return here if here is not None else self.intake.field_to_local(self.estimator.reading_ne(t)[0])

    def remember(self, t: float, blobs: list[Blob], camera_ne: np.ndarray, cell: np.ndarray,
                 cov_ne: np.ndarray) -> None:
        """Remember the targets found at simulated time t where the autopilot reads them, for
        `known` to recognise when they are seen again, and the cell each stands on where the
        camera's estimate (field frame, covariance cov_ne) makes it sure (RECORD_P per axis)
        and agrees with the commanded cell: a cell recorded wrong would lock every later
        registration on it a cell off (flight seed 11: 146 moves; held-out 30 and 34)."""
        reading = self.reading_at(t)
        for b in blobs:
            off = np.asarray(b.offset_ne(self.spec.camera_height()))
            self._found_at.append((t, reading + off))
            at = camera_ne + off
            x, y = (int(v) for v in nearest_cell(at))
            sure = lattice_p(np.abs(at - cell_to_ned(np.array([x, y]))), np.diag(cov_ne) + b.sd_m**2) >= RECORD_P
            ok = (x, y) == (int(cell[0]), int(cell[1])) and bool(sure.all())
            self._found_cells.append((x, y) if ok else None)
            self._told_cells.append((int(cell[0]), int(cell[1])))
