"""Issue 29's fleet flights measured (`uavsearch flight-table --agents N`): N vehicles on our
SITL fleet (one process), the fleet companion over real MAVLink, one flight per seed, scored
against the truth (missions.fleet_trial): truly found, separation refused, the least true
distance between airborne vehicles, and the flight's makespan over the team grid world's on the
same episode, starts, planner and seed. Writes OUT/fleet_flights.json and OUT/fleet_flights.md
(provenance stamped) and OUT/seed-S/ (report, logs, the tracks' plot) per seed."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from missions.fleet_trial import fly_fleet_trial
from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig

#: what each flight's row keeps of its trial report
ROW_KEYS = ("seed", "outcome", "moves", "grid_makespan", "flight_grid_ratio", "truly_found", "believed_found",
            "separation_refused", "min_true_separation_m", "min_true_separation_same_height_m",
            "min_true_distance_3d_m", "closest_true", "min_separation_m", "duplicate_finds", "lost",
            "schedule_slips", "late_frames", "simulated_s", "wall_s")


def fleet_flight_table(vehicles: int, grid: GridConfig, seeds: list[int], out: Path, speedup: float = 10.0,
                       physics: str = "pybullet", command: str = "uavsearch flight-table --agents",
                       echo: Callable[[str], None] = print, autopilot: str = "ours") -> dict[str, Any]:
    """Fly every seed with `vehicles` vehicles on one field; write the table; return its document.
    autopilot "ardupilot": each vehicle a real ArduCopter SITL on our world (missions.fleet_trial)."""
    if vehicles < 2:
        raise ValueError(f"a fleet needs at least 2 vehicles (got {vehicles})")
    rows = []
    t0 = time.monotonic()
    for s in seeds:
        r = fly_fleet_trial(out / f"seed-{s}", vehicles, grid, s, speedup, physics, autopilot=autopilot)
        rows.append({k: r[k] for k in ROW_KEYS})
        echo(f"seed {s}: {r['moves']} moves (grid {r['grid_makespan']}), {r['truly_found']}/{grid.n_targets} truly "
             f"found, {r['separation_refused']} refused, least {r['min_true_separation_m']} m, {r['wall_s']:.0f} s")
    ratio = np.array([r["flight_grid_ratio"] for r in rows])
    summary = {"flights": len(rows),
               "truly_found_pct": 100.0 * sum(r["truly_found"] for r in rows) / (grid.n_targets * len(rows)),
               "separation_refused": int(sum(r["separation_refused"] for r in rows)),
               "min_true_separation_m": min(r["min_true_separation_m"] for r in rows),
               "min_true_separation_same_height_m": min(r["min_true_separation_same_height_m"] for r in rows),
               "min_true_distance_3d_m": min(r["min_true_distance_3d_m"] for r in rows),
               "flight_grid_mean": float(ratio.mean()), "flight_grid_max": float(ratio.max()),
               "moves_mean": float(np.mean([r["moves"] for r in rows])),
               "grid_mean": float(np.mean([r["grid_makespan"] for r in rows])), "wall_s": time.monotonic() - t0}
    config = {"vehicles": vehicles, "grid": grid.to_dict(), "seeds": seeds, "speedup": speedup, "physics": physics,
              "policy": "belief-team (perfect sharing, one companion)", "command": command,
              **({} if autopilot == "ours" else {"autopilot": autopilot})}
    doc = stamp(config, seeds[0], summary=summary, flights=rows)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "fleet_flights.json", doc)
    with atomic_open(out / "fleet_flights.md", "w") as f:
        f.write(markdown(doc))
    return doc


def markdown(doc: dict[str, Any]) -> str:
    c, s = doc["config"], doc["summary"]
    g = c["grid"]
    seeds = c["seeds"]
    lines = [f"# Fleet flights: {c['vehicles']} vehicles, {g['width']} x {g['height']} / {g['n_targets']}, "
             f"seeds {seeds[0]}-{seeds[-1]}", "",
             f"Command: `{c['command']}` (git {doc['git_revision']}).", "",
             f"- truly found: {s['truly_found_pct']:.1f} %; separation refused: {s['separation_refused']}; "
             f"least true horizontal distance between airborne vehicles: {s['min_true_separation_m']} m, "
             f"between two within 1 m of one height: {s['min_true_separation_same_height_m']} m; least "
             f"distance in space: {s['min_true_distance_3d_m']} m",
             f"- makespan flight/grid: mean {s['flight_grid_mean']:.3f}, max {s['flight_grid_max']:.3f} "
             f"({s['moves_mean']:.1f} rounds flown against {s['grid_mean']:.1f} joint steps)", "",
             "| seed | moves | grid | flight/grid | truly found | refused | least true sep. (m) | at one height (m) "
             "| in space (m) | slips | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in doc["flights"]:
        lines.append(f"| {r['seed']} | {r['moves']} | {r['grid_makespan']} | {r['flight_grid_ratio']:.2f} | "
                     f"{r['truly_found']}/{g['n_targets']} | {r['separation_refused']} | {r['min_true_separation_m']} | "
                     f"{r['min_true_separation_same_height_m']} | {r['min_true_distance_3d_m']} | "
                     f"{sum(r['schedule_slips'])} | {r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"
