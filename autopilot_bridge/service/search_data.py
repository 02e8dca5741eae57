"""What the operator and the policy service exchange: the field's spec in, the search log and
the per-decision progress out, and the log's atomic save.

Its own module because these are plain data: missions (CLI, reports, progress bars) import
them without the service's threads and link, and the service's parts (telemetry intake,
registration, the setpoint stream, the decision loop) share them without importing one another.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sim.gridworld import GridConfig
from sim.gridworld.geodesy import HomePosition

from ..detection.detector import CAMERA_BELOW_M
from .fence import FencePlan
from .field_area import FieldArea

VISIT_MAPS = ("probabilistic", "hard")


@dataclass(frozen=True)
class SearchSpec:
    """What the operator tells the companion computer about the field."""

    origin: HomePosition  # the WGS84 position of cell (0, 0)'s centre
    grid: GridConfig = field(default_factory=GridConfig)
    altitude_m: float = 3.5
    arrive_m: float = 0.25
    max_moves: int | None = None  # default: the grid's t_e
    #: simulated seconds per decision: a 2 m leg and settling fit inside (sim targets step on it)
    decision_period_s: float = 4.0
    #: "probabilistic": visits spread over the position posterior; "hard": the believed cell only
    visit_map: str = "probabilistic"
    #: on the probabilistic map, a decision whose posterior puts at least this much in the
    #: believed cell takes the position as exact (map and policy): the crisp world the policy
    #: plans in (a soft map of a position that is known anyway only blurs it). 1.0: never
    exact_above: float = 0.9
    #: register the GPS bias: the launch point and targets on cell centres measure the true
    #: position, and setpoints are shifted by the estimated bias so the camera is truly over
    #: the cell it is meant to be over (False: fly in the GPS-estimate frame, as before)
    register: bool = True
    #: the map and the view place the camera by the autopilot's smooth estimate less the
    #: estimated bias (False: by the companion's posterior mean, which also carries its fixes'
    #: white noise)
    map_from_reading: bool = True
    #: the field has a visible edge (a track or stubble round the grass, `sim.vehicle.field`):
    #: a border not in view is then evidence the camera is further from it than the frame
    #: reaches (`Registration.register_unseen_edges`). A border seen registers either way
    field_edge: bool = False
    #: the vehicle's companion-loss failsafe, read before take-off (autopilot_bridge.service.preflight):
    #: False refuses a vehicle it would leave flying, True sets the safe values (logged)
    set_failsafe: bool = False
    #: where the vehicle truly stands at launch (field north, east m: its surveyed pad), which
    #: the launch registration takes as the truth beside its fixes; None: HOME_POSITION, which
    #: is that pad on our SITL but the GPS's (biased) fix at arming on a real autopilot
    launch_ne: tuple[float, float] | None = None
    #: the field's fence, uploaded, read back and enabled before take-off, which is refused
    #: when that fails or home lies outside (autopilot_bridge.service.fence); None: no fence is sent
    fence: FencePlan | None = None
    #: a real field (`field_area.FieldArea.of_field`): the grid at its heading (the companion then
    #: works in the grid's frame), only its searchable cells searched and flown to, its polygon's
    #: edges the borders registered on; None: today's north-aligned rectangle, every cell
    area: FieldArea | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.decision_period_s) and self.decision_period_s > 0):
            raise ValueError(f"decision_period_s must be > 0 (got {self.decision_period_s})")
        if self.visit_map not in VISIT_MAPS:
            raise ValueError(f"visit_map must be one of {VISIT_MAPS} (got {self.visit_map!r})")
        if not 0.0 < self.exact_above <= 1.0:
            raise ValueError(f"exact_above must be in (0, 1] (got {self.exact_above})")
        if self.area is not None and self.area.mask.shape != (self.grid.height, self.grid.width):
            raise ValueError(f"the field's mask is {self.area.mask.shape[1]} x {self.area.mask.shape[0]} cells, "
                             f"the grid {self.grid.width} x {self.grid.height}")

    def camera_height(self) -> float:
        """The camera's height over the (flat) field: the autopilot holds the commanded height
        on its barometer (decimetres of drift)."""
        return self.altitude_m - CAMERA_BELOW_M


@dataclass
class SearchLog:
    cells: list[tuple[int, int]] = field(default_factory=list)
    believed_found: list[int] = field(default_factory=list)  # move index of each believed find
    posterior_sd_m: list[float] = field(default_factory=list)
    decision_ms: list[float] = field(default_factory=list)
    #: per decision: the simulated time of its frame and fixes, and the position posterior then
    times_s: list[float] = field(default_factory=list)
    posterior_mean_ne: list[list[float]] = field(default_factory=list)
    posterior_cov_ne: list[list[list[float]]] = field(default_factory=list)
    #: per decision: the target channel of the 3 x 3 view I the detector made of the frame
    seen: list[list[list[int]]] = field(default_factory=list)
    #: per decision: the targets' blobs registered as position measurements (0 when ambiguous)
    registered: list[int] = field(default_factory=list)
    #: per decision: the field's borders seen and registered, [axis (0 north, 1 east), side (+1
    #: north / east border), the border's offset from the camera (m)] (autopilot_bridge.localisation.edges);
    #: on a polygon field [the outer ring's edge, its outward normal (north, east), its offset
    #: from the camera along it (m)] (`edges.find_ring_edges`)
    edges: list[list[list[float]]] = field(default_factory=list)
    #: what the companion learnt or changed before take-off (the autopilot, stream refusals,
    #: failsafe parameters set by --set-failsafe), a line each
    preflight: list[str] = field(default_factory=list)
    #: per decision: whether the position was taken as exact (the believed cell held >= exact_above)
    exact: list[bool] = field(default_factory=list)
    #: per decision: where the map and the view placed the camera (field north, east)
    camera_ne: list[list[float]] = field(default_factory=list)
    #: every setpoint sent (local north, east; the autopilot's estimate frame)
    setpoints_local: list[list[float]] = field(default_factory=list)
    #: on a real field (SearchSpec.area): where each setpoint sends the vehicle truly (field
    #: NED about cell (0, 0): the setpoint less the registered bias), for the scorer's checks
    setpoint_field_ne: list[list[float]] = field(default_factory=list)
    #: times the vehicle centred over a target in its cell before deciding (no move counted)
    recentred: int = 0
    #: times centring on a target put the camera over the next cell (the search went on there)
    centred_into_next: int = 0
    #: per decision: the altitude level flown (1 without levels) and the camera's height over
    #: the field its frame was read at (m: the commanded one, or with levels the one flown)
    levels_flown: list[int] = field(default_factory=list)
    camera_height_m: list[float] = field(default_factory=list)
    #: per decision: the targets seen, [north, east] offsets from the camera (m)
    blobs: list[list[list[float]]] = field(default_factory=list)
    frames: int = 0
    frames_missing: int = 0
    #: times the schedule slipped half a period because a leg had not settled at t_k
    schedule_slips: int = 0
    #: frames captured after their time because this computer asked too late (too slow for
    #: the simulation's speed-up): those decisions are not reproducible
    late_frames: int = 0
    #: waits for a fix or an estimate sample stamped before a decision that gave up (lost on
    #: the link, or this computer too loaded): those decisions may differ from run to run
    late_inputs: int = 0
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


def save_log(log: SearchLog, path: Path, **extra: Any) -> None:
    """The search log, plus anything the caller adds (how the flight ended, provenance)."""
    from dataclasses import asdict

    from provenance import atomic_write_json

    atomic_write_json(path, {**asdict(log), **extra})
