"""Position registration: the GPS-free measurements of where the camera truly is (the memory of
the targets found is `found.FoundTargets`).

Its own part of the service because GPS alone puts the camera a metre or more off (the
receiver's bias): the launch point (the vehicle standing on home before arming) and targets
standing on cell centres measure the true position, so the bias is registered and the camera
flown truly over each cell; a found target seen again measures it on its known cell.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np

from sim.gridworld import cell_to_ned

from ..detection.detector import Blob
from ..detection.found import FOUND_M, FoundTargets
from ..detection.view import blob_cells
from ..link.connection import VehicleLink
from ..service.search_data import SearchSpec
from .edges import EdgeSighting, RingEdgeSighting, border_ne, find_ring_edges, half_footprint_m
from .estimator import GpsEstimator
from .team_finds import TeamFoundTargets
from .telemetry import READING_SD_M, TelemetryIntake

log = logging.getLogger(__name__)

#: the launch point (home, the spawn cell's centre) as a position measurement while the vehicle
#: stands on it disarmed: sd of where the vehicle stands on its pad (m)
LAUNCH_SD_M = 0.05
#: simulated seconds of fixes on the launch point registered before arming
LAUNCH_S = 2.0
#: a re-sighting of a found target is fused unless it is this many sigmas off the posterior
KNOWN_GATE = 5.0
#: the standard deviation a re-sighting of a found target is fused with (m): the same cow seen
#: again from about the same spot errs the same way (its heading moves the blob's centre), so
#: its sightings are not independent; fused at the detector's 0.3 m, 20 flights had a mean NEES
#: of 3.6
KNOWN_SD_M = 0.5
#: an edge sighting's error (m): the border's place in the frame (rendered at the true height:
#: 0.05 m sd, max 0.09) and the camera's height, by which the offset is scaled: the autopilot
#: holds the commanded height on its barometer, which drifts (0.2 m sd in the simulator), so a
#: border 3 m out reads 0.2 m off. Flown: 0.11 m sd within 1 m of the nadir, 0.25 m at 3-4 m
EDGE_SD_M = 0.08
EDGE_HEIGHT_SD_M = 0.25
#: an edge sighting this many sigmas off the posterior along its axis says the posterior is
#: wrong (a lattice registered a cell off), not the edge: the split of the GPS reading into
#: position and bias is doubted first (`GpsEstimator.doubt_split`), so the edge moves the
#: estimate to it instead of being averaged with a wrong frame
EDGE_DOUBT = 3.0
#: a border this far inside the frame's edge (m) is seen (rendered: every border 0.3 m or more
#: inside, 532 of 532): one not seen is further out than the frame reaches, less this
EDGE_REACH_MARGIN_M = 0.4


class Registration:
    """Registers the launch point and targets as position measurements into the estimator
    (found targets on the cells `FoundTargets` keeps for them)."""

    def __init__(self, link: VehicleLink, spec: SearchSpec, estimator: GpsEstimator,
                 intake: TelemetryIntake, found: FoundTargets | None = None) -> None:
        self.link, self.spec, self.estimator, self.intake = link, spec, estimator, intake
        self.launch_registered = False
        #: the camera's height over the field the frames are read at (m): the spec's commanded
        #: one, or the height flown (the service sets autopilot_bridge.service.height.FlownHeight's)
        self.camera_height: Callable[[], float] = spec.camera_height
        #: the targets found: which of a frame's blobs they are, and the cells they stand on
        self.found = found if found is not None else FoundTargets(spec, estimator, intake)

    def register_launch(self) -> None:
        """Disarmed on the ground, the vehicle stands on its launch point (SearchSpec.launch_ne,
        its surveyed pad; else home, HOME_POSITION in the field frame, which our SITL sets there): each fix of LAUNCH_S simulated seconds is fused
        with that true position beside it, which averages the receiver's white noise out of
        the GPS bias, so the first cells are flown truly over their centres. (The vehicle waits
        disarmed for this companion, so those seconds are on the ground in every run.)"""
        if not self.spec.register or self.link.telemetry.armed or self.intake.first_fix_t is None:
            return
        t_start, t_end = self.launch_window()
        # every fix stamped up to t_end has arrived once a later one has
        self.link.wait_for(lambda: self.intake.last_gps_t > t_end + 1e-6, 30.0, f"GPS fixes after {t_end:.1f} s")
        home = self.intake.home_in_field()[:2] if self.spec.launch_ne is None else np.asarray(self.spec.launch_ne)
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

    def register_edges(self, t: float, edges: list[EdgeSighting]) -> int:
        """The field's borders seen in the frame: each measures where the camera truly is along
        its axis (the border's place less its offset from the nadir), exactly, whatever the
        targets do (moving herds too). Fused before the targets, so the lattice's hypotheses
        are weighed against a frame the edge has already put right. The grid's rectangle only: a
        polygon's edges are read at any angle (`register_ring_edges`). Returns how many."""
        if not self.spec.register or not edges or self.spec.area is not None:
            return 0
        g, height = self.spec.grid, self.camera_height()
        used = 0
        for e in edges:
            sd = _edge_sd(e.offset_m, height)
            post = self.estimator.posterior(t)
            z = border_ne(e.axis, e.side, g.width, g.height) - e.offset_m
            r = z - float(post.mean_ned[e.axis])
            if r * r > EDGE_DOUBT**2 * (float(post.horizontal_cov[e.axis, e.axis]) + sd**2):
                self.estimator.doubt_split(abs(r), (e.axis,))
            self.estimator.observe_position(t, np.array([z]), sd, (e.axis,))
            used += 1
        return used

    def ring_edges(self, t: float, frame: np.ndarray, camera_height_m: float, fov_deg: float) -> list[RingEdgeSighting]:
        """A polygon field's edges seen in the frame (the camera this high), at any angle
        (`edges.find_ring_edges`), looked for about where the posterior puts the camera at t;
        [] on the rectangle."""
        area = self.spec.area
        if not self.spec.register or area is None:
            return []
        return find_ring_edges(frame, camera_height_m, area.outer_grid, self.estimator.posterior(t).mean_ned[:2],
                               fov_deg)

    def register_ring_edges(self, t: float, edges: list[RingEdgeSighting]) -> int:
        """A polygon field's edges seen in the frame: each measures how far the camera truly is
        from its line, across it (the edge's place along its normal less its offset from the
        nadir), and nothing along it: one measurement along the edge's normal, whatever its
        angle to the grid. Before, only the edges along a grid axis were read (the farm: one of
        five; flight seed 9 then went 40 decisions uncorrected along the slanted sides and
        truly 1.28 m past the ring). Doubted as a border is (EDGE_DOUBT). Returns how many."""
        area = self.spec.area
        if not self.spec.register or not edges or area is None:
            return 0
        height = self.camera_height()
        for e in edges:
            n = np.asarray(e.normal_ne, dtype=float)
            sd = _edge_sd(e.offset_m, height)
            post = self.estimator.posterior(t)
            z = float(n @ area.outer_grid[e.edge]) - e.offset_m
            r = z - float(n @ post.mean_ned[:2])
            if r * r > EDGE_DOUBT**2 * (float(n @ post.horizontal_cov @ n) + sd**2):
                self.estimator.doubt_split_along(abs(r), n)
            self.estimator.observe_along(t, n, z, sd)
        return len(edges)

    def register_unseen_edges(self, t: float, edges: list[EdgeSighting], fov_deg: float) -> None:
        """The borders not seen in a frame are further from the camera than it reaches: each
        weighs the position posterior's lattice hypotheses by how likely they put the camera
        that far in (`GpsEstimator.observe_bound`). A frame a cell off towards a border would
        have had it in view (flight seed 154: the camera believed a cell east, 3 m from the east
        border, which the frame did not show; a cow registered there for 5 decisions)."""
        if not self.spec.register or not self.spec.field_edge or self.spec.area is not None:
            return  # (a polygon's borders not seen: not yet weighed)
        g, height = self.spec.grid, self.camera_height()
        reach = half_footprint_m(height, fov_deg) - EDGE_REACH_MARGIN_M
        sd = _edge_sd(reach, height)
        seen = {(e.axis, e.side) for e in edges}
        for axis in (0, 1):
            for side in (1, -1):
                if (axis, side) not in seen:
                    # side +1: the border lies north (east) of the camera, which is then south
                    # (west) of it by more than the reach
                    self.estimator.observe_bound(t, axis, border_ne(axis, side, g.width, g.height) - side * reach,
                                                 side > 0, sd)

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
        height = self.camera_height()
        for b in sorted(blobs, key=lambda b: b.fuse_sd_m(height)):
            if b.beyond_view(height):
                continue
            sd = b.fuse_sd_m(height)
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
                self.estimator.observe_position(t, z[list(forced)], sd, forced)
            for i in soft:
                # the cell it stands on along this axis and the field's cells either side of it
                # (north is -y, east is x), as a mixture weighed by the posterior's components
                idx, size = (on[1], g.height) if i == 0 else (on[0], g.width)
                near = [j for j in (idx - 1, idx, idx + 1) if 0 <= j < size]
                centres = np.array([-cell_m * j if i == 0 else cell_m * j for j in near])
                self.estimator.observe_position_mixture(t, i, centres - offset[i], sd)
            used += 1
            if on == (int(cell[0]), int(cell[1])) and not b.at_edge and np.abs(offset).max() > FOUND_M:
                off_centre = True
        return used, off_centre

    def register_known(self, t: float, blobs: list[Blob],
                       ids: list[int | None] | None = None) -> tuple[int, list[Blob]]:
        """A static target found before stands on a known cell, and which one the receiver
        frame says (its reading matches, `match`), whatever the position posterior: a sighting
        of it measures where the camera truly is with no lattice ambiguity. Without this the
        GPS bias went unobserved while the vehicle worked around found targets with a posterior
        too wide to register new sightings (flight seed 18: the camera drifted 1-1.5 m off its
        cells for 30 moves, and the view put a found cow a cell off). A blob cut by the frame's
        edge registers the axis along the cut only. ids: the frame's blobs identified
        (`FoundTargets.identify`; worked out here if None). Returns how many were fused and the blobs left for
        `register_targets`: those not found before, and found ones whose cell was not sure."""
        if not self.spec.register or self.spec.grid.moving or not len(self.found):
            return 0, blobs
        height = self.camera_height()
        ids = self.found.identify(t, blobs) if ids is None else ids
        used, rest = 0, []
        for b, i in zip(blobs, ids, strict=True):
            off = np.asarray(b.offset_ne(height))
            if b.beyond_view(height):
                i = None
            if i is None:
                rest.append(b)
                continue
            team = isinstance(self.found, TeamFoundTargets) and self.found.is_team(i)
            if team:
                # a teammate's find (localisation.team_finds): where its finder placed it, fused
                # with the finder's variance added, gated on the two estimates' together
                if not self.found.register_landmarks:
                    continue
                at, var = self.found.team_landmark(i)
            else:
                on = self.found.cell_of(i)
                if on is None:  # its cell unsure: registered by the lattice odds now, as any target
                    rest.append(b)
                    continue
                at, var = cell_to_ned(np.array(on)), np.zeros(2)
            # a blob cut by the frame's edge: the axis across the cut is left out (its centre
            # 0.2-0.45 m off), the other kept (rendered cut cows: 0.14 m rms along it, as
            # inside the frame). Cut blobs had been left out whole: flight seed 69 then missed
            # a found cow's east offset while the bias drifted 0.6 m in 4 s
            axes = [i for i, cut in enumerate(b.cut_axes) if not cut]
            if not axes:
                continue
            z = (at - off)[axes]
            sd = math.sqrt(KNOWN_SD_M**2 + float(np.max(var[axes])))
            post = self.estimator.posterior(t)
            r = z - post.mean_ned[axes]
            cov = post.horizontal_cov[np.ix_(axes, axes)] + np.eye(len(axes)) * sd**2
            q = float(r @ np.linalg.solve(cov, r))
            if team and q > EDGE_DOUBT**2:
                # matched a cell off (`TeamFoundTargets.assign_team`: this frame on the wrong
                # lattice point): the split of the GPS reading is doubted, as an edge's, so the
                # landmark moves the estimate to it, not averaged with the wrong frame
                self.estimator.doubt_split(float(np.abs(r).max()), tuple(axes))
            elif q > KNOWN_GATE**2:
                continue  # not where that target could be seen from: a wrong match
            self.estimator.observe_position(t, z, sd, tuple(axes))
            used += 1
            if team:
                self.found.team.count(self.found.team.registrations, self.found.vehicle)
        return used, rest


def _edge_sd(offset_m: float, camera_height_m: float) -> float:
    """The sd (m) of a border read this far from the nadir: the frame's (EDGE_SD_M) and the
    height's error scaling the offset (EDGE_HEIGHT_SD_M)."""
    return math.hypot(EDGE_SD_M, offset_m * EDGE_HEIGHT_SD_M / camera_height_m)
