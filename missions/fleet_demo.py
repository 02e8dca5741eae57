"""`uavsearch demo --agents N` (issue 29): N simulated quadrotors search one field together.

The fleet's flight as a demo: our SITL fleet (sim.mavlink.SitlFleet, one process, each vehicle
its own MAVLink endpoint and camera, on its own start cell of one field), the fleet companion
(missions.fleet_flight: one process, a link per vehicle, one shared belief, the team planner in
rounds, the separation check on every setpoint, distinct search heights) over real MAVLink on
UDP loopback, scored against the simulator's truth (missions.fleet_trial). Writes OUT/report.md
(what a reader opens first: the numbers and the tracks' picture), OUT/report.json,
OUT/fleet_log.json, OUT/vehicle-I/search_log.json and OUT/fleet.png.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from provenance import atomic_open
from sim.gridworld import GridConfig


def fly_fleet_demo(out: Path, agents: int, grid: GridConfig, seed: int, speedup: float, command: str,
                   echo: Callable[[str], None] = print) -> dict[str, Any]:
    """Fly the fleet's search once and write its report; returns the trial's report."""
    from missions.fleet_trial import fly_fleet_trial

    if agents < 2:
        raise ValueError(f"a fleet demo flies 2 or more vehicles (got {agents})")
    out = Path(out)
    echo(f"flying {agents} vehicles on one {grid.width} x {grid.height} field ({grid.n_targets} targets, seed {seed}) "
         f"at {speedup:g}x: our SITL fleet, one companion over MAVLink, one shared belief...")
    r = fly_fleet_trial(out, agents, grid, seed, speedup, "pybullet")
    finds = json.loads((out / "fleet_log.json").read_text())["outcome"]["team"]["finds"]
    with atomic_open(out / "report.md", "w") as f:
        f.write(report_markdown(r, finds, command))
    return r


def report_markdown(r: dict[str, Any], finds: list, command: str) -> str:
    """The demo's report: what flew, what it found (truth), how close the vehicles came, the
    picture. r: the trial's report; finds: the team's (round, vehicle, cell)."""
    c = r["config"]
    g = c["grid"]
    n = c["vehicles"]
    lines = [f"# {n} UAVs searching one {g['width']} x {g['height']} field together", "",
             f"Command: `{command}` (git {r['git_revision']}, seed {r['seed']}).", "",
             f"{n} simulated quadrotors (our SITL fleet: PyBullet, one process; each vehicle its own MAVLink endpoint "
             "and camera, on its own start cell) flown by one companion process over MAVLink (UDP loopback): one "
             "shared belief, the team belief planner in rounds, the separation check on every setpoint, each "
             f"vehicle at its own search height ({', '.join(f'{h:g}' for h in c['altitudes_m'])} m). Found targets "
             "are shared between the vehicles as landmarks (docs/fleet_flight.md).", "",
             "| | |", "|---|---|",
             f"| outcome | exit {r['outcome']}{'' if not r.get('cause') else ': ' + str(r['cause'])} |",
             f"| targets truly found | {r['truly_found']}/{r['targets']} (the team believed {r['believed_found']}) |",
             f"| rounds (joint moves) | {r['moves']} (the team grid world on the same episode: {r['grid_makespan']}; "
             f"flight/grid {r['flight_grid_ratio']:.2f}) |",
             f"| setpoints refused by the separation check | {r['separation_refused']} |",
             f"| least true distance between airborne vehicles | {_m(r['min_true_distance_3d_m'])} in space; "
             f"{_m(r['min_true_separation_same_height_m'])} horizontally within 1 m of one height |",
             f"| simulated / wall | {r['simulated_s']:.0f} s / {r['wall_s']:.0f} s ({c['speedup']:g}x) |", "",
             "| vehicle | start cell | height (m) | targets it found (round: cell) |", "|---|---|---|---|"]
    for i in range(n):
        mine = ", ".join(f"{rd}: ({x}, {y})" for rd, v, (x, y) in finds if v == i) or "-"
        start = c["starts"][i]
        lines.append(f"| {i} | ({start[0]}, {start[1]}) | {c['altitudes_m'][i]:g} | {mine} |")
    lines += ["", "![every vehicle's decided cells (dots), true track (faint), the targets (truth) and the team's "
              "finds](fleet.png)", "",
              "Files: report.json (this, with config, seed and git revision), fleet_log.json (the team's rounds, "
              "finds and separation record), vehicle-I/search_log.json (each vehicle's decisions), fleet.png.", ""]
    return "\n".join(lines)


def _m(v: float | None) -> str:
    return "-" if v is None else f"{v:.2f} m"
