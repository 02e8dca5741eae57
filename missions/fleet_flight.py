"""A fleet's search flight (issue 29): one companion process, N vehicles on their own links,
one shared belief and the team planner (autopilot_bridge.service.fleet says why one process).

Each vehicle is flown by its own PolicyService on its own thread inside missions.guarded's
`guarded_search`, so each keeps every safety path of a lone flight (docs/safety.md): whatever
stops its search, its setpoints stop and it is brought down (LAND by default here: a vehicle
descends where it is, crossing no one's leg, where RTL would fly it home across the field).
On top, the fleet's main thread:
- holds SIGINT / SIGTERM: a signal stops the fleet, and every vehicle is brought down;
- watches the links (`TeamRound.monitor`): a vehicle silent, disarmed or on the ground during
  the search is lost, taken out of the team (brought down by its thread, or by its own
  offboard-loss failsafe where its link is dead) and the others re-plan without it;
- an exception in a vehicle's search that is not a lost vehicle (a bug, the planner failing)
  stops the fleet: all are brought down.
The exit status is a lone flight's (missions.guarded): 0 every target found by the team,
3 the search ended short, 1 a failure, 128 + N a signal.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.fleet import (
    HEIGHT_STEP_M,
    FleetPlanner,
    GuardedFrames,
    SeparationCheck,
    TeamRound,
)
from autopilot_bridge.service.policy_service import PolicyService, SearchSpec, save_log
from missions.guarded import (
    EXIT_FAILED,
    EXIT_OK,
    EXIT_SHORT,
    FlightEnd,
    Interrupted,
    guarded_search,
    signals_raise,
)
from provenance import atomic_write_json, stamp
from sim.gridworld import GridConfig

#: the failures that mean "this vehicle is gone", not "the companion is broken": the vehicle is
#: taken out and the others fly on (autopilot_bridge.link.LinkError and its kin, the fleet's own)
LOST_CAUSES = ("LinkError", "VehicleLost", "WrongAutopilot", "CommandRejected", "CameraNotFound")


@dataclass(frozen=True)
class FleetEnd:
    exit_code: int
    cause: str | None
    vehicles: list[FlightEnd | None]
    team: TeamRound

    @property
    def found(self) -> int:
        return len(self.team.log.finds)

    def to_dict(self) -> dict[str, Any]:
        return {"exit_code": self.exit_code, "cause": self.cause, "found": self.found,
                "vehicles": [None if v is None else v.to_dict() for v in self.vehicles],
                "team": self.team.log.to_dict()}


def build_team(links: Sequence[VehicleLink], specs: Sequence[SearchSpec], seed: int,
               frames: Sequence[Any] | None = None, separation: SeparationCheck | None = None,
               round_timeout_s: float = 30.0) -> tuple[TeamRound, list[PolicyService]]:
    """The fleet's companion: one PolicyService per vehicle (seed + i: its own tie-break
    stream), its policy the team's proxy, its frames guarded; one team planner (seed)."""
    from autopilot_bridge.camera import MavlinkCamera

    n = len(links)
    grid = specs[0].grid
    if any(s.grid != grid for s in specs):
        raise ValueError("every vehicle of a fleet flies one field: the grids differ")
    if grid.levels > 1:
        raise ValueError("a fleet flies one height (altitude levels: one vehicle at a time so far)")
    areas = [s.area for s in specs]
    if any(a is not None for a in areas) and (any(a is None for a in areas) or
                                              any(not np.array_equal(a.mask, areas[0].mask) for a in areas)):
        raise ValueError("every vehicle of a fleet flies one field: the real fields' masks differ")
    planner = FleetPlanner()
    planner.reset_team(grid, n, seed, mask=None if areas[0] is None else areas[0].mask)
    team = TeamRound(n, planner, grid, separation, round_timeout_s)
    services = []
    for i, (link, spec) in enumerate(zip(links, specs, strict=True)):
        src = frames[i] if frames is not None else MavlinkCamera(link)
        services.append(PolicyService(link, team.proxies[i], spec, seed + i, frames=GuardedFrames(src, team, i)))
    team.attach(services)
    return team, services


def fly_fleet(team: TeamRound, services: Sequence[PolicyService], on_abort: str = "land",
              abort_timeout_s: float = 120.0, move_timeout_s: float = 20.0,
              echo: Callable[[str], None] = print, poll_s: float = 0.1) -> FleetEnd:
    """Fly every vehicle's search at once and bring every one down, whatever happens."""
    n = len(services)
    ends: list[FlightEnd | None] = [None] * n
    said = threading.Lock()  # one line at a time from the vehicles' threads
    shown = echo

    def echo(m: str) -> None:
        with said:
            shown(m)

    def fly(i: int) -> None:
        say = lambda m: echo(f"vehicle {i}: {m}")  # noqa: E731
        try:
            end = guarded_search(services[i], services[i].link, on_abort, abort_timeout_s, echo=say,
                                 move_timeout_s=move_timeout_s)
        except BaseException as e:  # noqa: BLE001 - guarded_search brings the vehicle down; never silently
            team.stop(f"vehicle {i}: {type(e).__name__}: {e}")
            team.leave(i, f"{type(e).__name__}: {e}")
            raise
        ends[i] = end
        failed = end.exit_code not in (EXIT_OK, EXIT_SHORT)
        if failed and team.stop_cause is None and not team.finished:
            if not (end.cause or "").startswith(LOST_CAUSES):
                team.stop(f"vehicle {i}: {end.cause}")  # a bug, not a lost vehicle: everyone down
            else:
                echo(f"vehicle {i} is out of the team ({end.cause}); the others go on")
        team.leave(i, end.cause if failed else None)

    threads = [threading.Thread(target=fly, args=(i,), name=f"fleet-vehicle-{i}", daemon=True) for i in range(n)]
    code: int | None = None
    cause: str | None = None
    with signals_raise() as sig:
        try:
            for t in threads:
                t.start()
            while any(t.is_alive() for t in threads):
                sig.raise_pending()
                team.monitor()
                time.sleep(poll_s)
        except (Interrupted, KeyboardInterrupt) as e:
            signum = e.signum if isinstance(e, Interrupted) else signal.SIGINT
            sig.bringing_down = True
            cause, code = f"interrupted by {signal.Signals(signum).name}", 128 + signum
            echo(f"fleet stopped: {cause}; bringing every vehicle down")
            team.stop(cause)
            for t in threads:
                while t.is_alive():
                    t.join(0.2)
                    team.monitor()
    if code is None:
        if team.stop_cause is not None:
            cause, code = team.stop_cause, EXIT_FAILED
        elif team.finished:
            cause, code = None, EXIT_OK
        elif len(team.log.lost) == n:
            cause, code = "every vehicle was lost", EXIT_FAILED
        else:
            cause = f"the search ended after {team.log.rounds} rounds with {len(team.log.finds)} of " \
                    f"{team.grid.n_targets} targets found"
            code = EXIT_SHORT
    return FleetEnd(code, cause, ends, team)


def save_fleet(out: Path, end: FleetEnd, services: Sequence[PolicyService], config: dict[str, Any], seed: int,
               title: str) -> None:
    """OUT/fleet_log.json (the team's record), OUT/vehicle-I/search_log.json, OUT/fleet.png."""
    out.mkdir(parents=True, exist_ok=True)
    for i, s in enumerate(services):
        v = out / f"vehicle-{i}"
        v.mkdir(exist_ok=True)
        save_log(s.log, v / "search_log.json", outcome=None if end.vehicles[i] is None else end.vehicles[i].to_dict(),
                 provenance=stamp(config, seed + i, vehicle=i))
    atomic_write_json(out / "fleet_log.json", stamp(config, seed, outcome=end.to_dict()))
    from missions.fleet_plot import plot_fleet

    plot_fleet(out / "fleet.png", services[0].spec.grid, [s.log.cells for s in services], end.team.log.finds, title)


def specs_from_fields(paths: Sequence[Path], altitude: float = 3.5, max_moves: int | None = None,
                      set_failsafe: bool = False) -> tuple[list[SearchSpec], list[str], GridConfig]:
    """The vehicles' specs and addresses from the field files `sitl --count N --one-field`
    wrote; every problem names the file (FieldFileError)."""
    from missions.fieldfile import FieldFileError, read_field

    if len(paths) < 2:
        raise FieldFileError(f"a fleet needs two or more field files (got {len(paths)})")
    fields = [read_field(p) for p in paths]
    first = fields[0]
    for p, f in zip(paths, fields, strict=True):
        if f.team != len(paths):
            raise FieldFileError(f"{p}: not one of a fleet of {len(paths)} on one field (team {f.team}): start the "
                                 f"vehicles with `uavsearch sitl --count {len(paths)} --one-field`")
        if (f.origin, f.grid, f.cell_m) != (first.origin, first.grid, first.cell_m):
            raise FieldFileError(f"{p}: another field than {paths[0]}'s (origin, size or targets differ)")
        if not f.connect:
            raise FieldFileError(f"{p}: names no address to connect to")
    if first.grid.levels > 1:
        raise FieldFileError(f"{paths[0]}: {first.grid.levels} altitude levels: a fleet flies one height's cells "
                             "for now (docs/fleet_flight.md, Left)")
    if len({f.polygon for f in fields}) != 1:
        raise FieldFileError(f"the field files name different real fields ({sorted({str(f.polygon) for f in fields})})")
    real: dict[str, Any] = {}
    if first.polygon is not None:  # a real field: its mask searched, its fence on every vehicle
        from missions.field_run import field_spec, load_polygon

        try:
            pf = load_polygon(Path(first.polygon))
        except (OSError, ValueError) as e:
            raise FieldFileError(f"{paths[0]}: its real field {first.polygon}: {e}") from e
        if (pf.width, pf.height) != (first.grid.width, first.grid.height):
            raise FieldFileError(f"{paths[0]}: the real field {first.polygon} is {pf.width} x {pf.height}, the file's "
                                 f"grid {first.grid.width} x {first.grid.height}")
        real = field_spec(pf)
    addresses = [f.connect for f in fields]
    if len(set(addresses)) != len(addresses):
        raise FieldFileError(f"two field files name one address ({addresses}): one link per vehicle")
    top = altitude + (len(fields) - 1) * HEIGHT_STEP_M
    if top > 30.0:
        raise FieldFileError(f"{len(fields)} vehicles from {altitude:g} m, {HEIGHT_STEP_M:g} m apart, reach {top:g} m "
                             "above home: more than 30 m")
    # vehicle i at altitude + i * HEIGHT_STEP_M (autopilot_bridge.service.fleet: one cell of position
    # error must not put two vehicles in one place)
    # a real autopilot's home is its GPS fix at arming: each vehicle's pad is given (its field file's)
    specs = [SearchSpec(f.origin, f.grid, altitude + i * HEIGHT_STEP_M, max_moves=max_moves, field_edge=f.edge,
                        set_failsafe=set_failsafe, launch_ne=f.launch_ne, **real) for i, f in enumerate(fields)]
    return specs, addresses, first.grid


def run_fleet(paths: Sequence[Path], out: Path, seed: int = 0, on_abort: str = "land", altitude: float = 3.5,
              max_moves: int | None = None, move_timeout_s: float = 20.0, abort_timeout_s: float = 120.0,
              tlog: bool = True, echo: Callable[[str], None] = print, set_failsafe: bool = False) -> int:
    """`uavsearch run --fleet FIELD...`: connect to every vehicle, search, land; the exit status.
    A vehicle whose field file names a camera of its own (a camera component beside a real
    autopilot, `sitl --autopilot ardupilot --count N --one-field`) is watched there, each
    vehicle's link in the dialect its HEARTBEAT names."""
    from missions.fieldfile import FieldFileError, read_field

    try:
        specs, addresses, grid = specs_from_fields(paths, altitude, max_moves, set_failsafe)
        cameras = [read_field(p).camera for p in paths]
    except FieldFileError as e:
        echo(f"error: {e}")
        return 2
    out.mkdir(parents=True, exist_ok=True)
    config = {"fleet": [str(p) for p in paths], "connect": addresses, "grid": grid.to_dict(), "policy": "belief-team",
              "altitude": altitude, "altitudes_m": [s.altitude_m for s in specs], "max_moves": max_moves, "on_abort": on_abort}
    links: list[VehicleLink] = []
    opened: list[Any] = []  # the cameras of their own this companion opened, closed with the links
    try:
        for i, a in enumerate(addresses):
            links.append(VehicleLink(a, tlog=out / f"companion-{i}.tlog" if tlog else None,
                                     tlog_meta=stamp(config, seed, kind="companion tlog", vehicle=i)))
        echo(f"fleet of {len(links)} on a {grid.width} x {grid.height} field, {grid.n_targets} targets; team "
             f"belief planner, one shared belief; connecting to {', '.join(addresses)} (on abort: {on_abort})")
        frames = None
        if any(c is not None for c in cameras):
            from autopilot_bridge.camera import CameraNotFound, MavlinkCamera, open_source

            frames = []
            for i, (c, link) in enumerate(zip(cameras, links, strict=True)):
                if c is None:
                    frames.append(MavlinkCamera(link))
                    continue
                try:  # before anything flies: a camera not answering is one clear line, nothing armed
                    opened.append(open_source(c, link, timeout_s=30.0, tlog=out / f"camera-{i}.tlog" if tlog else None))
                except CameraNotFound as e:
                    echo(f"error: vehicle {i}: {e}")
                    return EXIT_FAILED
                frames.append(opened[-1])
        team, services = build_team(links, specs, seed, frames=frames)
        end = fly_fleet(team, services, on_abort, abort_timeout_s, move_timeout_s, echo)
    finally:
        for f in opened:
            f.close()
        for link in links:
            link.close()
    log = end.team.log
    save_fleet(out, end, services, config, seed,
               f"fleet of {len(links)}: {log.rounds} rounds, {end.found}/{grid.n_targets} found")
    echo(f"{log.rounds} rounds, {end.found}/{grid.n_targets} targets found by the team; separation: "
         f"{log.separation_refused} setpoints refused, least {_m(log.min_separation_m)} between airborne vehicles; "
         f"lost: {len(log.lost)}; log and plot in {out}")
    if end.cause is not None:
        echo(("warning: " if end.exit_code == EXIT_SHORT else "error: ") + end.cause)
    return end.exit_code


def _m(v: float) -> str:
    return "-" if not np.isfinite(v) else f"{v:.1f} m"
