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

from sim.gridworld import cell_to_ned, nearest_cell

from .detector import Blob, blob_cells
from .estimator import GpsEstimator
from .link import VehicleLink
from .search_data import SearchSpec
from .telemetry import TelemetryIntake

log = logging.getLogger(__name__)

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
        height = self.spec.camera_height()
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

    def new_targets(self, t: float, blobs: list[Blob], cell: np.ndarray,
                    camera_ne: np.ndarray) -> tuple[list[Blob], list[Blob]]:
        """The targets in this cell not found before: (those under the camera, those beside it).

        Under the camera: the blob's (GPS-free) offset is within FOUND_M of the nadir on both
        axes, so the vehicle is truly over it, whichever cell the posterior puts it in. Beside
        it: in the believed cell, the camera placed at camera_ne (field north, east: the view's
        placement, so a target the view shows in the centre slot is under the camera or beside
        it, never neither), further off (not cut by the frame's edge).
        Found before: the target's position in the autopilot's frame (`reading_at`: truth +
        GPS bias) is within half a cell of a target found (or seen again) earlier; the two
        readings differ by the bias's drift in between (0.26 m sd over a decision, 0.8 m over
        minutes). Without this a target found a cell off the nadir, or
        seen from the next cell with the posterior a metre off, was found twice (20 flights:
        84 % truly found, every flight believing 5/5)."""
        height = self.spec.camera_height()
        reading = self.reading_at(t)
        below: list[Blob] = []
        aside: list[Blob] = []
        for b in blobs:
            if b.beyond_view(height):
                continue
            off = np.asarray(b.offset_ne(height))
            if self.known(t, reading + off):
                continue
            if np.abs(off).max() <= FOUND_M:
                below.append(b)
            elif not b.at_edge and (np.abs(off).max() <= NEAR_M
                                    or blob_cells([b], camera_ne, height)[0] == (int(cell[0]), int(cell[1]))):
                aside.append(b)
        aside.sort(key=lambda b: float(np.abs(b.offset_ne(height)).max()))
        return below, aside

    def known(self, t: float, at_reading: np.ndarray) -> bool:
        """A target seen at this receiver-frame position is one found before (nearest lattice
        offset between the two is zero); its entry is refreshed (a shorter drift next time)."""
        i = self.match(at_reading)
        if i is not None:
            self._found_at[i] = (t, at_reading)
        return i is not None

    def match(self, at_reading: np.ndarray) -> int | None:
        """The found target (its index) seen at this receiver-frame position, or None."""
        for i, (_, p) in enumerate(self._found_at):
            if np.all(np.abs(at_reading - p) < 1.0):  # half a 2 m cell
                return i
        return None

    def register_known(self, t: float, blobs: list[Blob]) -> tuple[int, list[Blob]]:
        """A static target found before stands on a known cell, and which one the receiver
        frame says (its reading matches, `match`), whatever the position posterior: a sighting
        of it measures where the camera truly is with no lattice ambiguity. Without this the
        GPS bias went unobserved while the vehicle worked around found targets with a posterior
        too wide to register new sightings (flight seed 18: the camera drifted 1-1.5 m off its
        cells for 30 moves, and the view put a found cow a cell off). Cut blobs are left out
        (their centres are 0.2-0.45 m off). Returns how many were fused and the blobs that
        are not found targets, for `register_targets`."""
        if not self.spec.register or self.spec.grid.moving or not self._found_cells:
            return 0, blobs
        height = self.spec.camera_height()
        reading = self.reading_at(t)
        used, rest = 0, []
        for b in blobs:
            off = np.asarray(b.offset_ne(height))
            i = None if b.beyond_view(height) else self.match(reading + off)
            if i is None:
                rest.append(b)
                continue
            on = self._found_cells[i]
            if on is None or b.at_edge:
                continue
            z = cell_to_ned(np.array(on)) - off
            post = self.estimator.posterior(t)
            r = z - post.mean_ned[:2]
            if float(r @ np.linalg.solve(post.horizontal_cov + np.eye(2) * KNOWN_SD_M**2, r)) > KNOWN_GATE**2:
                continue  # not where that target could be seen from: a wrong match
            self.estimator.observe_position(t, z, KNOWN_SD_M)
            used += 1
        return used, rest

    def reading_at(self, t: float) -> np.ndarray:
        """Where the autopilot puts the vehicle at simulated time t (local north, east): its
        estimate is the truth plus the GPS bias, smooth (the receiver's white noise is filtered
        out by its inertial fusion), so two readings of one spot a few seconds apart differ by
        the bias's drift only. (The companion's own p + b is noisier: readings of one cow over
        16 s scattered by +-1 m.) Without telemetry then: the companion's p + b."""
        here = self.intake.local_at(t)
        return here if here is not None else self.intake.field_to_local(self.estimator.reading_ne(t)[0])

    def remember(self, t: float, blobs: list[Blob], camera_ne: np.ndarray, cell: np.ndarray) -> None:
        """Remember the targets found at simulated time t where the autopilot reads them, for
        `known` to recognise when they are seen again, and the cell each stands on where the
        camera's estimate (field frame) agrees with the commanded cell: a cell recorded wrong
        would lock every later registration on it a cell off (flight seed 11: 146 moves)."""
        reading = self.reading_at(t)
        for b in blobs:
            off = np.asarray(b.offset_ne(self.spec.camera_height()))
            self._found_at.append((t, reading + off))
            x, y = (int(v) for v in nearest_cell(camera_ne + off))
            self._found_cells.append((x, y) if (x, y) == (int(cell[0]), int(cell[1])) else None)
