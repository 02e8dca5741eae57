"""Issue 29's fleet flight measured: N vehicles on our SITL fleet (one process), the fleet
companion over real MAVLink, one flight per seed, scored against the truth
(missions.fleet_trial): truly found, separation refused, the least true distance between
airborne vehicles, and the flight's makespan over the team grid world's on the same episode,
starts, planner and seed. Writes OUT/fleet_flights.json and OUT/fleet_flights.md (provenance
stamped), and OUT/seed-S/ (report, logs, the tracks' plot) per seed.

    PYTHONPATH=. .venv/bin/python benchmarks/fleet_flight_table.py --vehicles 4 --width 20 --height 20 \\
        --targets 10 --seeds 0-9 --speedup 10 --out results/fleet
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from missions.fleet_trial import fly_fleet_trial
from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig


def seeds_of(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, default=4)
    ap.add_argument("--width", type=int, default=20)
    ap.add_argument("--height", type=int, default=20)
    ap.add_argument("--targets", type=int, default=10)
    ap.add_argument("--seeds", default="0-9", help="first-last (inclusive)")
    ap.add_argument("--speedup", type=float, default=10.0)
    ap.add_argument("--physics", default="pybullet")
    ap.add_argument("--out", type=Path, default=Path("results/fleet"))
    a = ap.parse_args()
    grid = GridConfig(width=a.width, height=a.height, n_targets=a.targets)
    seeds = seeds_of(a.seeds)
    rows = []
    t0 = time.monotonic()
    for s in seeds:
        r = fly_fleet_trial(a.out / f"seed-{s}", a.vehicles, grid, s, a.speedup, a.physics)
        rows.append({k: r[k] for k in ("seed", "outcome", "moves", "grid_makespan", "flight_grid_ratio",
                                       "truly_found", "believed_found", "separation_refused", "min_true_separation_m",
                                       "min_true_separation_same_height_m", "min_true_distance_3d_m",
                                       "closest_true",
                                       "min_separation_m", "duplicate_finds", "lost", "schedule_slips", "late_frames",
                                       "simulated_s", "wall_s")})
        print(f"seed {s}: {r['moves']} moves (grid {r['grid_makespan']}), {r['truly_found']}/{a.targets} truly found, "
              f"{r['separation_refused']} refused, least {r['min_true_separation_m']} m, {r['wall_s']:.0f} s", flush=True)
    ratio = np.array([r["flight_grid_ratio"] for r in rows])
    summary = {"flights": len(rows), "truly_found_pct": 100.0 * sum(r["truly_found"] for r in rows) / (a.targets * len(rows)),
               "separation_refused": int(sum(r["separation_refused"] for r in rows)),
               "min_true_separation_m": min(r["min_true_separation_m"] for r in rows),
               "min_true_separation_same_height_m": min(r["min_true_separation_same_height_m"] for r in rows),
               "min_true_distance_3d_m": min(r["min_true_distance_3d_m"] for r in rows),
               "flight_grid_mean": float(ratio.mean()), "flight_grid_max": float(ratio.max()),
               "moves_mean": float(np.mean([r["moves"] for r in rows])),
               "grid_mean": float(np.mean([r["grid_makespan"] for r in rows])), "wall_s": time.monotonic() - t0}
    config = {"vehicles": a.vehicles, "grid": grid.to_dict(), "seeds": seeds, "speedup": a.speedup,
              "physics": a.physics, "policy": "belief-team (perfect sharing, one companion)",
              "command": "benchmarks/fleet_flight_table.py " + " ".join(
                  f"--{k} {v}" for k, v in (("vehicles", a.vehicles), ("width", a.width), ("height", a.height),
                                            ("targets", a.targets), ("seeds", a.seeds), ("speedup", a.speedup),
                                            ("out", a.out)))}
    doc = stamp(config, seeds[0], summary=summary, flights=rows)
    atomic_write_json(a.out / "fleet_flights.json", doc)
    lines = [f"# Fleet flights: {a.vehicles} vehicles, {a.width} x {a.height} / {a.targets}, seeds {a.seeds}", "",
             f"Command: `PYTHONPATH=. .venv/bin/python {config['command']}` (git {doc['git_revision']}).", "",
             f"- truly found: {summary['truly_found_pct']:.1f} %; separation refused: {summary['separation_refused']}; "
             f"least true horizontal distance between airborne vehicles: {summary['min_true_separation_m']} m, "
             f"between two within 1 m of one height: {summary['min_true_separation_same_height_m']} m; least "
             f"distance in space: {summary['min_true_distance_3d_m']} m",
             f"- makespan flight/grid: mean {summary['flight_grid_mean']:.3f}, max {summary['flight_grid_max']:.3f} "
             f"({summary['moves_mean']:.1f} rounds flown against {summary['grid_mean']:.1f} joint steps)", "",
             "| seed | moves | grid | flight/grid | truly found | refused | least true sep. (m) | at one height (m) "
             "| in space (m) | slips | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['seed']} | {r['moves']} | {r['grid_makespan']} | {r['flight_grid_ratio']:.2f} | "
                     f"{r['truly_found']}/{a.targets} | {r['separation_refused']} | {r['min_true_separation_m']} | "
                     f"{r['min_true_separation_same_height_m']} | {r['min_true_distance_3d_m']} | "
                     f"{sum(r['schedule_slips'])} | {r['wall_s']:.0f} |")
    with atomic_open(a.out / "fleet_flights.md", "w") as f:
        f.write("\n".join(lines) + "\n")
    print(summary)


if __name__ == "__main__":
    main()
