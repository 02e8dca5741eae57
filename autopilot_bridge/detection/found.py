"""The targets found: the companion's memory of them, and which blobs of a frame they are.

Its own part of the service because a target seen again must not be found twice: it is
remembered where the autopilot read it (truth + GPS bias, smooth), so one seen again from the
next cell, or with the position posterior a metre off, is recognised by the bias's drift in
between; the cell it stands on is kept where the camera was sure of it (for `Registration`
to measure the camera's position on it), and the cell the policy was told (where the view
shows it from then on).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment

from sim.gridworld import cell_to_ned, nearest_cell

from ..localisation.estimator import GpsEstimator
from ..localisation.telemetry import TelemetryIntake
from ..service.search_data import SearchSpec
from .detector import Blob, px_per_m
from .view import FAR_REACH_M, blob_cells

#: a found target's cell is recorded (for `Registration.register_known`) only where the
#: posterior makes it this probable per axis at the find: a cow found with the camera estimate
#: 1-1.5 m off was recorded a cell off and every re-sighting then locked the frame there
#: (held-out flight seeds 30 and 34: NEES 9)
RECORD_P = 0.9
#: a target counts as found when the camera is truly over it: its centre within this of the
#: nadir on both axes (the scorer's half cell less the detector's error); a target in the
#: believed cell but further off is re-centred on first (at most RECENTRE times a move)
FOUND_M = 0.8
#: a new target this near the nadir (m, both axes) is beside the camera whichever cell the
#: camera estimate puts it in: with the camera 0.5-0.8 m off its cell either cell is likely,
#: and labelled into the neighbour, the cow's own cell was marked seen-empty with the camera
#: beside it (flight seed 13: 25 moves back and forth next to it). It is centred on first
NEAR_M = 1.3
#: the offsets (north, east m) between a cell and its eight neighbours
_NEIGHBOURS = np.array([(dn, de) for dn in (-2.0, 0.0, 2.0) for de in (-2.0, 0.0, 2.0) if dn or de])
#: sd of one blob's offset (m) in matching two sightings (the detector's, inside the frame)
MATCH_SD_M = 0.3
#: sd of a blob's offset across a frame edge that cuts it (m): its centre there is censored
#: (rendered cut cows: 0.2-0.45 m off, up to a metre where little of the cow shows)
CUT_SD_M = 0.6


def same_or_new(same: np.ndarray, new: np.ndarray, floor: float | None = None) -> list[int | None]:
    """Each sighting (row j) as one of the k known targets or as a new one, one to one, the
    likeliest joint assignment (`linear_sum_assignment`): same (m, k) the log-likelihoods that
    sighting j is target i, new (m,) that it is a target not yet known (a column of its own).
    floor: a pairing at or below it counts as new (a score that means "impossible")."""
    m, k = same.shape
    score = np.full((m, k + m), -1e9)
    score[:, :k] = same
    score[np.arange(m), k + np.arange(m)] = new
    rows, cols = linear_sum_assignment(-score)
    out: list[int | None] = [None] * m
    for j, c in zip(rows, cols, strict=True):
        out[int(j)] = int(c) if c < k and (floor is None or same[int(j), int(c)] > floor) else None
    return out


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


class FoundTargets:
    """The targets found (in the autopilot's frame), and which blobs of a frame they are."""

    def __init__(self, spec: SearchSpec, estimator: GpsEstimator, intake: TelemetryIntake) -> None:
        self.spec, self.estimator, self.intake = spec, estimator, intake
        #: the camera's height over the field the blobs are read at (m): the spec's commanded
        #: one, or the height flown (the service sets autopilot_bridge.service.height.FlownHeight's)
        self.camera_height: Callable[[], float] = spec.camera_height
        #: targets found (or seen again since): (simulated time, receiver-frame north, east)
        self._found_at: list[tuple[float, np.ndarray]] = []
        #: the field cell each found target stands on, by _found_at's index; None where the
        #: camera's estimate and the commanded cell disagreed on it
        self._found_cells: list[tuple[int, int] | None] = []
        #: the cell the policy was told each found target is in (the commanded cell at the find)
        self._told_cells: list[tuple[int, int]] = []

    def __len__(self) -> int:
        return len(self._found_at)

    def cell_of(self, i: int) -> tuple[int, int] | None:
        """The field cell found target i stands on, or None where that was not sure."""
        return self._found_cells[i]

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
        GPS bias) matches a target found (or seen again) earlier (`identify`); the two
        readings differ by the bias's drift in between (0.26 m sd over a decision, 0.8 m over
        minutes). Without this a target found a cell off the nadir, or
        seen from the next cell with the posterior a metre off, was found twice (20 flights:
        84 % truly found, every flight believing 5/5)."""
        height = self.camera_height()
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
            if np.abs(off).max() <= FOUND_M:
                below.append(b)
            elif ((not b.at_edge and np.abs(off).max() <= NEAR_M)
                  or blob_cells([b], camera_ne, height)[0] == (int(cell[0]), int(cell[1]))):
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
        height = self.camera_height()
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
        return same_or_new(same, new)

    def told_cells(self, t: float, blobs: list[Blob],
                   ids: list[int | None] | None = None) -> list[tuple[int, int] | None]:
        """Per blob: the cell the policy was told it is in where it is a target found before
        (matched by the autopilot's reading, `identify`), else None. The view shows a found target
        there, wherever the camera estimate now puts it: the policy's world shows found targets
        where they were found, and one shown a cell away was a target it had not found, which
        it chased back and forth (flight seed 9: 54 moves against 22 in the grid world)."""
        height = self.camera_height()
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
            off = np.asarray(b.offset_ne(self.camera_height()))
            self._found_at.append((t, reading + off))
            at = camera_ne + off
            x, y = (int(v) for v in nearest_cell(at))
            sure = lattice_p(np.abs(at - cell_to_ned(np.array([x, y]))), np.diag(cov_ne) + b.sd_m**2) >= RECORD_P
            ok = (x, y) == (int(cell[0]), int(cell[1])) and bool(sure.all())
            self._found_cells.append((x, y) if ok else None)
            self._told_cells.append((int(cell[0]), int(cell[1])))
