"""A fleet's found targets shared between its vehicles: each vehicle's finds are landmarks for
every other vehicle's identification and registration (issue 29).

Why: each vehicle's `FoundTargets` remembers its own finds where its own autopilot read them
(truth + its receiver's GPS bias), which is what recognises a target it sees again; another
vehicle's receiver has another bias, so those readings say nothing to it. Alone, a vehicle
whose estimate had drifted a cell off flew over a target a teammate had found and took it for
a new one in the cell beside it (20 x 20 / 10, 4 vehicles, seed 2: vehicle 1 1.75 m north of
where it believed, posterior sd 0.65 m, over vehicle 3's find; the team believed 10 found, 9
truly). Shared, a teammate's find is placed in the field frame (where the finder's camera
estimate put it, with the finder's posterior variance then), and a blob of vehicle B that no
find of its own explains is matched against those in B's field frame (its camera estimate,
with its own posterior variance): the two frames' errors are independent, so the gate is their
combined variance, and the alternative is the same as for B's own finds, a new target on a cell
next to the teammate's, a priori as likely as a cell holding a target. Matched, the target is
not a new find (B's view shows it on the cell its finder told the team), and it registers B's
position as B's own finds do (`Registration.register_known`), fused with the finder's variance
added to the re-sighting's.

The teammate's variance is the finder's posterior at the find, never the lattice-snapped cell
it may have recorded as sure: a finder a cell off is as sure of its wrong cell as of a right
one (seed 2's vehicle 1 recorded its find 1.8 m north at p 0.96), and a well-placed teammate
gated on that would have found the target a second time beside it.

One process holds the fleet (autopilot_bridge.service.fleet), so the registry is one object
shared by the vehicles' threads (a lock around it); a find made in a round is seen by the
others from their next frame on.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from ..detection.detector import Blob
from ..detection.found import _NEIGHBOURS, CUT_SD_M, FOUND_M, MATCH_SD_M, FoundTargets, same_or_new
from ..service.search_data import SearchSpec
from .edges import half_footprint_m
from .estimator import GpsEstimator
from .telemetry import TelemetryIntake

#: the prior probability that a vehicle's estimate is a whole cell off, whatever its posterior
#: says (4 vehicles, 20 x 20 / 10, seeds 2 and 3: 5-18 of a vehicle's 36-39 decisions were over
#: another cell than it believed, 1-1.8 m off, far from the field's edges and its finds)
OFF_CELL = 0.1
#: a sighting further than this many sigmas from a find, and than GATE_OFF_CELL from it a
#: cell off, is not it (two cells off is not one cell off and 2 m of error)
GATE = 5.0
GATE_OFF_CELL = 3.0
#: the chance the detector misses a target whole in the frame, inside its edge by
#: IN_VIEW_MARGIN_M (registration's 0.4 m reach margin and half a metre for the estimates)
MISS_P = 0.05
IN_VIEW_MARGIN_M = 0.9
#: a blob within this many sigmas of where a find would show is taken to be it showing
GATE_SHOWN = 3.0
#: the cell size (m): targets stand on a lattice of cell centres this far apart
CELL_M = 2.0
#: posterior components lighter than this are left out of the matching
MIN_COMPONENT_W = 0.01
#: ids of teammates' finds, as `TeamFoundTargets.identify` returns them: this plus the index in
#: the registry (a vehicle's own finds keep their indices, 0, 1, ...)
TEAM_ID = 1_000_000


@dataclass(frozen=True)
class TeamFind:
    """One target found by one vehicle, as the team keeps it."""

    vehicle: int
    t: float
    #: where the finder put the target (field north, east) and that estimate's variance per
    #: axis (the finder's posterior then plus its blob's)
    ne: np.ndarray
    var_ne: np.ndarray
    #: the cell the finder told the team (its commanded cell: where the team's belief has it)
    told: tuple[int, int]


class TeamFinds:
    """The fleet's registry of finds, shared by every vehicle's `TeamFoundTargets` (thread-safe)."""

    def __init__(self) -> None:
        self._finds: list[TeamFind] = []
        self._lock = threading.Lock()
        #: per vehicle: blobs identified as a teammate's find, and of those, ones under the
        #: camera (a find a lone vehicle would have made again), and registrations on them
        self.sightings: dict[int, int] = {}
        self.not_new: dict[int, int] = {}
        self.registrations: dict[int, int] = {}

    def add(self, find: TeamFind) -> None:
        with self._lock:
            self._finds.append(find)

    def snapshot(self) -> list[TeamFind]:
        with self._lock:
            return list(self._finds)

    def __getitem__(self, j: int) -> TeamFind:
        with self._lock:
            return self._finds[j]

    def count(self, what: dict[int, int], vehicle: int, n: int = 1) -> None:
        with self._lock:
            what[vehicle] = what.get(vehicle, 0) + n

    def to_dict(self) -> dict[str, object]:
        with self._lock:
            return {"finds": [{"vehicle": f.vehicle, "t": round(f.t, 3), "ne": np.round(f.ne, 3).tolist(),
                               "sd_ne": np.round(np.sqrt(f.var_ne), 3).tolist(), "told": list(f.told)}
                              for f in self._finds],
                    "sightings": {str(k): v for k, v in sorted(self.sightings.items())},
                    "not_new": {str(k): v for k, v in sorted(self.not_new.items())},
                    "registrations": {str(k): v for k, v in sorted(self.registrations.items())}}


class TeamFoundTargets(FoundTargets):
    """Vehicle `vehicle`'s found-targets memory in a fleet: its own finds as a lone vehicle's,
    then its teammates' (from `team`) for the blobs its own do not explain. Teammates' finds get
    ids TEAM_ID + j; `Registration.register_known` fuses them by `team_landmark`."""

    def __init__(self, spec: SearchSpec, estimator: GpsEstimator, intake: TelemetryIntake,
                 team: TeamFinds, vehicle: int, fov_deg: float = 100.0) -> None:
        """fov_deg: the camera's field of view (the detector's): how far out a find shows."""
        super().__init__(spec, estimator, intake)
        self.team, self.vehicle, self.fov_deg = team, vehicle, fov_deg
        #: whether a teammate's find seen registers this vehicle's position (False: it is only
        #: told apart from a new find)
        self.register_landmarks = True

    def __len__(self) -> int:
        """Own finds and teammates' (so `register_known` looks at a frame once a teammate found one)."""
        return super().__len__() + sum(f.vehicle != self.vehicle for f in self.team.snapshot())

    @staticmethod
    def is_team(i: int | None) -> bool:
        return i is not None and i >= TEAM_ID

    def camera_components(self, t: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """Where this vehicle's camera is at simulated time t (field north, east), per component
        of its position posterior (one per lattice hypothesis): (weight, placement, variance per
        axis). Each placed as the service places the camera for its view (the autopilot's
        reading less that component's bias, `PolicyService._place`), else at its mean. Per
        component, not the likeliest one's placement with the mixture's variance: that wide
        variance made a new target a cell beside a teammate's find look like the find (seed 8:
        vehicle 0, its posterior split between its true cell and the next, took a new cow for
        the find two cells off, which was then found 44 rounds later)."""
        weights, means, covs = self.estimator.components(t)
        bias = self.estimator.component_bias()
        here = self.intake.local_at(t)
        placed = here is not None and self.spec.register and self.spec.map_from_reading
        origin = self.intake.local_origin_in_field()[:2] if placed else None
        out = []
        for w, mean, cov, b in zip(weights, means, covs, bias, strict=True):
            if w < MIN_COMPONENT_W:
                continue
            at = here + origin - b[:2] if placed else mean[:2]
            out.append((float(w), np.asarray(at, dtype=float), np.diag(cov[:2, :2]).copy()))
        return out

    def identify(self, t: float, blobs: list[Blob]) -> list[int | None]:
        """Per blob: its own find (as a lone vehicle's, `FoundTargets.identify`), else a
        teammate's (TEAM_ID + j, `assign_team`), else None."""
        ids = super().identify(t, blobs)
        rest = [j for j, i in enumerate(ids) if i is None]
        finds = [(j, f) for j, f in enumerate(self.team.snapshot()) if f.vehicle != self.vehicle]
        if not rest or not finds:
            return ids
        height = self.camera_height()
        offsets = [self._match_offset(blobs[j], height) for j in rest]
        got = self.assign_team(offsets, [blobs[j].cut_axes for j in rest], [f for _, f in finds],
                               self.camera_components(t))
        for j, k in zip(rest, got, strict=True):
            if k is not None:
                ids[j] = TEAM_ID + finds[k][0]
                self.team.count(self.team.sightings, self.vehicle)
        return ids

    def assign_team(self, offsets: list[np.ndarray], cuts: list[tuple[bool, bool]], finds: list[TeamFind],
                    cameras: list[tuple[float, np.ndarray, np.ndarray]]) -> list[int | None]:
        """Which of the teammates' finds (index into finds), if any, each sighting is, jointly,
        one to one. Sighting j is a blob at offsets[j] (north, east m) from the nadir; the camera
        is at one of `cameras` (weight, field position, variance per axis: the posterior's
        components, `camera_components`), the sighting at that plus its offset. Against find i,
        per camera hypothesis (the likelihoods summed over them by weight):

        - the same target: the two positions differ by the two estimates' errors and the two
          blobs' (variances summed: the vehicles' errors are independent), or, with probability
          OFF_CELL, by a whole cell more (this vehicle's estimate on the wrong lattice point,
          which its posterior does not know: seed 2's vehicle 1 was 1.8 m off at 0.1 m sd, its
          frame locked on its own find recorded a cell off). Beyond GATE sigmas of the first
          and GATE_OFF_CELL of the second: not it;
        - a new target on a cell centre (the field's lattice, this camera's error and one
          blob's between), a priori as likely as a cell holding a target (`FoundTargets.assign`'s
          prior; there the lattice is the find's neighbours, the reading frame knowing no cell
          centres). Then this vehicle's frame is right, and every find stands where its finder
          put it in this frame: a find well inside the frame that no other blob is at is one the
          detector missed, as likely as MISS_P. That decides the lattice ambiguity a posterior
          cannot: a target seen a cell off a teammate's find is that find unless the find shows
          beside it. (The same penalty holds under "the same target" for the other finds shown:
          it weighs the camera hypotheses too.)"""
        m, k = len(offsets), len(finds)
        g = self.spec.grid
        p_new = min(g.n_targets / (g.width * g.height), 0.5)
        reach = half_footprint_m(self.camera_height(), self.fov_deg) - IN_VIEW_MARGIN_M
        off = np.asarray(offsets, dtype=float).reshape(m, 2)
        same_l = np.zeros((m, k))  # likelihoods, summed over the camera hypotheses by weight
        new_l = np.zeros(m)
        total_w = sum(w for w, _, _ in cameras)
        prior = p_new / (1.0 - p_new)
        for w, cam, cam_var in cameras:
            at = cam + off
            # the finds this frame shows if this hypothesis is right, and per find which blobs
            # are where it would show: a find shown that no blob but j explains is missed by
            # the detector (MISS_P) unless j is it
            shown = [i for i, f in enumerate(finds) if np.all(np.abs(f.ne - cam) <= reach)]
            near = np.zeros((len(shown), m), bool)
            for a_, i in enumerate(shown):
                base = cam_var + finds[i].var_ne + 2.0 * MATCH_SD_M**2
                near[a_] = np.sum((at - finds[i].ne) ** 2 / base, axis=1) <= GATE_SHOWN**2
            for j, cut in enumerate(cuts):
                others = np.delete(near, j, axis=1).any(axis=1) if m > 1 else np.zeros(len(shown), bool)
                missing = [i for a_, i in enumerate(shown) if not others[a_]]
                # a new target: on the field's lattice of cell centres, this camera's error and
                # one blob's between
                v = cam_var + MATCH_SD_M**2 + np.where(cut, CUT_SD_M**2, 0.0)
                r = at[j] - CELL_M * np.round(at[j] / CELL_M)
                new_l[j] += (w / total_w * _gauss(r, v) * prior * MISS_P ** len(missing))
                for i, f in enumerate(finds):
                    v = cam_var + f.var_ne + 2.0 * MATCH_SD_M**2 + np.where(cut, CUT_SD_M**2, 0.0)
                    d = at[j] - f.ne
                    q0 = float(np.sum(d * d / v))
                    qn = np.sum((d - _NEIGHBOURS) ** 2 / v, axis=1)
                    if q0 <= GATE**2 or float(qn.min()) <= GATE_OFF_CELL**2:
                        fit = ((1.0 - OFF_CELL) * math.exp(-0.5 * q0)
                               + OFF_CELL / len(_NEIGHBOURS) * float(np.exp(-0.5 * qn).sum()))
                        same_l[j, i] += (w / total_w * _gauss(np.zeros(2), v) * fit
                                         * MISS_P ** (len(missing) - (i in missing)))
        with np.errstate(divide="ignore"):
            same = np.where(same_l > 0, np.log(same_l), -1e9)
            new = np.maximum(np.log(new_l), -1e8)
        return same_or_new(same, new, floor=-1e9)

    def team_landmark(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Teammate's find i (an id from `identify`): where it stands (field north, east) and that
        position's variance per axis."""
        f = self.team[i - TEAM_ID]
        return f.ne, f.var_ne

    def cell_of(self, i: int) -> tuple[int, int] | None:
        """A teammate's find has no cell sure to this vehicle (`team_landmark` places it)."""
        return None if self.is_team(i) else super().cell_of(i)

    def new_targets(self, t: float, blobs: list[Blob], cell: np.ndarray, camera_ne: np.ndarray,
                    ids: list[int | None] | None = None) -> tuple[list[Blob], list[Blob]]:
        """As a lone vehicle's; a teammate's find is not new (counted where it is under the camera)."""
        ids = self.identify(t, blobs) if ids is None else ids
        height = self.camera_height()
        for b, i in zip(blobs, ids, strict=True):
            if self.is_team(i) and not b.beyond_view(height) and np.abs(np.asarray(b.offset_ne(height))).max() <= FOUND_M:
                self.team.count(self.team.not_new, self.vehicle)
        return super().new_targets(t, blobs, cell, camera_ne, ids)

    def _refresh(self, i: int, t: float, at_reading: np.ndarray, cut: tuple[bool, bool]) -> None:
        if not self.is_team(i):  # a teammate's find is kept in the field frame, not this receiver's
            super()._refresh(i, t, at_reading, cut)

    def told_cells(self, t: float, blobs: list[Blob],
                   ids: list[int | None] | None = None) -> list[tuple[int, int] | None]:
        """As a lone vehicle's; a teammate's find is shown on the cell its finder told the team."""
        ids = self.identify(t, blobs) if ids is None else ids
        own = super().told_cells(t, blobs, [None if self.is_team(i) else i for i in ids])
        height = self.camera_height()
        return [self.team[i - TEAM_ID].told if self.is_team(i) and not b.beyond_view(height) else c
                for b, i, c in zip(blobs, ids, own, strict=True)]

    def remember(self, t: float, blobs: list[Blob], camera_ne: np.ndarray, cell: np.ndarray,
                 cov_ne: np.ndarray) -> None:
        """As a lone vehicle's, and each find published to the team (its field position by this
        camera's estimate, with the posterior's variance and the blob's)."""
        super().remember(t, blobs, camera_ne, cell, cov_ne)
        height = self.camera_height()
        for b in blobs:
            ne = np.asarray(camera_ne, dtype=float) + np.asarray(b.offset_ne(height))
            self.team.add(TeamFind(self.vehicle, float(t), ne, np.diag(np.asarray(cov_ne)) + b.sd_m**2,
                                   (int(cell[0]), int(cell[1]))))


def _gauss(r: np.ndarray, v: np.ndarray) -> float:
    """The density of an axis-aligned Gaussian with variances v at r."""
    return float(np.exp(-0.5 * np.sum(r * r / v)) / (2.0 * math.pi * math.sqrt(float(np.prod(v)))))
