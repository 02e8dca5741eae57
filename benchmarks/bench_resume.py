"""Resume against starting over: searches whose companion is killed -9 at a random move, then
resumed from its journal (`uavsearch run --resume`), against the same seed flown from scratch
after the kill (the moves flown before it lost, then a whole search).

Per seed, each with a fresh SITL in this process (companion lockstep) and `uavsearch run` as a
process on a UDP loopback link (missions/resume_trial.py):
1. the search flown from scratch, uninterrupted: its moves M (what starting over costs after
   the kill) and whether it completed;
2. the same seed again, killed -9 at a move drawn from [3, M - 2] (seeded per seed), a random
   fraction of a decision after its progress line; then resumed: at once (the vehicle still in
   the air under its failsafe) for the even rows, after the vehicle has landed and disarmed
   (its failsafe brought it home) for the odd ones.
Total moves resumed: the resumed log's moves (the whole search, before and after the kill).
Starting over: the moves journaled before the kill + M.

    python benchmarks/bench_resume.py --seeds 101-110 --out results/resume.md
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from missions.resume_trial import (
    companion,
    kill_at_move,
    search_log,
    start_companion,
    truly_found,
    vehicle,
    wait_until,
)
from provenance import atomic_write_bytes, atomic_write_json, stamp
from sim.gridworld import GridConfig

ROOT = Path(__file__).resolve().parent.parent
BASE_PORT = 28500


def seeds_from(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def fly(tmp: Path, seed: int, port: int, grid: GridConfig, speedup: float, policy: str) -> dict:
    """The search from scratch: moves, exit, found."""
    out = tmp / f"fresh-{seed}"
    shutil.rmtree(out, ignore_errors=True)
    with vehicle(out.parent, seed, port, grid, speedup) as v:
        p, head = start_companion(v, "--field", str(v.field_file), "--out", str(out), "--seed", str(seed),
                                  "--policy", policy, "--no-tlog")
        text, _ = p.communicate(timeout=900)
        text = "".join(head) + text
        truly = truly_found(v)
    log = search_log(out)
    return {"moves": len(log["cells"]) - 1, "exit": p.returncode, "believed": len(log["believed_found"]),
            "truly": truly, "tail": text[-400:]}


def killed_and_resumed(tmp: Path, seed: int, port: int, grid: GridConfig, speedup: float, policy: str,
                       kill_move: int, delay_s: float, wait_landed: bool) -> dict:
    out = tmp / f"resumed-{seed}"
    shutil.rmtree(out, ignore_errors=True)
    with vehicle(out.parent, seed, port, grid, speedup) as v:
        p, head = start_companion(v, "--field", str(v.field_file), "--out", str(out), "--seed", str(seed),
                                  "--policy", policy, "--no-tlog")
        before = "".join(head) + kill_at_move(p, kill_move, delay_s, timeout=900)
        t_kill = time.monotonic()
        mode_at_kill = v.sitl.vehicle.mode
        landed = wait_until(lambda: v.landed_disarmed, 180) if wait_landed else False
        waited = time.monotonic() - t_kill
        r = companion("--resume", str(out), "--no-tlog")
        after, _ = r.communicate(timeout=900)
        truly = truly_found(v)
    log = search_log(out)
    rs = log.get("resumes", [])
    return {"kill_move": kill_move, "kill_delay_s": round(delay_s, 3), "killed_rc": p.returncode,
            "mode_at_kill": mode_at_kill, "waited_for_landing": wait_landed, "landed": landed,
            "wall_before_resume_s": round(waited, 1), "exit": r.returncode, "moves": len(log["cells"]) - 1,
            "believed": len(log["believed_found"]), "truly": truly, "resume": rs[0] if rs else None,
            "tail": (before[-300:] + "\n---\n" + after[-600:])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="101-110")
    ap.add_argument("--speedup", type=float, default=10.0)
    ap.add_argument("--policy", default="belief")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "resume.md")
    ap.add_argument("--work", type=Path, default=ROOT / "out" / "bench_resume",
                    help="The runs' directories (journals, logs, plots), kept for a look afterwards.")
    args = ap.parse_args()
    grid = GridConfig()
    rows = []
    t0 = time.monotonic()
    tmp = args.work
    for i, seed in enumerate(seeds_from(args.seeds)):
        fresh = fly(tmp, seed, BASE_PORT + 10 * (2 * i), grid, args.speedup, args.policy)
        rng = np.random.default_rng([seed, 0x4E5])
        kill = int(rng.integers(3, max(fresh["moves"] - 2, 4)))
        delay = float(rng.uniform(0.0, 0.4))
        res = killed_and_resumed(tmp, seed, BASE_PORT + 10 * (2 * i + 1), grid, args.speedup, args.policy,
                                 kill, delay, wait_landed=i % 2 == 1)
        before = res["resume"]["at_move"] if res["resume"] else None
        row = {"seed": seed, "fresh": fresh, "resumed": res,
               "complete": res["exit"] == 0 and res["believed"] == grid.n_targets,
               "moves_before_kill": before,
               "start_over_moves": None if before is None else before + fresh["moves"]}
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if k not in ("fresh", "resumed")}
                         | {"resumed_moves": res["moves"], "fresh_moves": fresh["moves"],
                            "how": res["resume"]["how"] if res["resume"] else None}), flush=True)
    wall = time.monotonic() - t0
    command = "python benchmarks/bench_resume.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    prov = stamp({"seeds": args.seeds, "speedup": args.speedup, "policy": args.policy, "grid": grid.to_dict(),
                  "lockstep": True}, None, command=command, wall_s=round(wall, 1))
    atomic_write_json(args.out.with_suffix(".json"), {"provenance": prov, "rows": rows})
    atomic_write_bytes(args.out, table(rows, prov, command).encode())
    print(f"wrote {args.out} ({wall:.0f} s)")


def table(rows: list[dict], prov: dict, command: str) -> str:
    done = sum(r["complete"] for r in rows)
    fewer = sum(1 for r in rows if r["start_over_moves"] is not None and r["resumed"]["moves"] < r["start_over_moves"])
    tot_res = sum(r["resumed"]["moves"] for r in rows)
    tot_over = sum(r["start_over_moves"] or 0 for r in rows)
    lines = [
        "# Resume after a companion crash against starting over",
        "",
        f"`{command}` (git {prov['git_revision']}, {prov['created_utc']}, {prov['wall_s']:.0f} s wall on a shared "
        "2-core machine). Our SITL (PyBullet, companion lockstep, speed-up "
        f"{prov['config']['speedup']:g}) in the benchmark's process, `uavsearch run --policy {prov['config']['policy']}` "
        "as a process on UDP loopback, 10 x 10 field, 5 static targets. Each seed is flown once from scratch "
        "(moves M), and once killed -9 at a seeded random move (a random fraction of a decision after its progress "
        "line) and resumed with `uavsearch run --resume`: at once for even rows (the vehicle in the air under its "
        "offboard-loss failsafe: hold, then return), after the vehicle landed and disarmed for odd rows. "
        "Resumed moves: the whole search's log (before and after the kill). Starting over: the moves journaled "
        "before the kill + M.",
        "",
        f"**{done}/{len(rows)} complete** (exit 0, 5/5 believed found); resumed with fewer moves than starting over "
        f"in {fewer}/{len(rows)}; moves in all: resumed {tot_res}, starting over {tot_over}.",
        "",
        "| seed | killed at move | resumed | vehicle found | rejoined | gap (sim s) | resumed: moves | found (believed / truly) "
        "| from scratch: moves | starting over: moves |",
        "|---:|---:|---|---|---|---:|---:|---|---:|---:|",
    ]
    for r in rows:
        res, fr = r["resumed"], r["fresh"]
        rj = res["resume"] or {}
        lines.append(
            f"| {r['seed']} | {r['moves_before_kill']} | {'after landing' if res['waited_for_landing'] else 'at once'} "
            f"| {'armed' if rj.get('armed_found') else 'disarmed'}, {rj.get('mode_found', '?')} | {rj.get('how', 'failed')} "
            f"| {rj.get('gap_s', float('nan')):.0f} | {res['moves']} | {res['believed']} / {res['truly']} "
            f"| {fr['moves']} | {r['start_over_moves']} |")
    lines += ["", "Rows and the companion's last output per run: `results/resume.json`.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
