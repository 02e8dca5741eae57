"""Many vehicles in one process (issue 13), side by side in one run:
- the fleet (`uavsearch sitl --count N`): one physics step and one vectorised controller for
  all vehicles, then each vehicle's MAVLink tick;
- the same N vehicles as N separate `Sitl` objects stepped one after the other (a Python loop
  per vehicle, each with its own physics world), as `--count N` ran before;
- the fleet's physics alone (no MAVLink endpoints), also with only some of 16 PyBullet vehicles
  flying (the others on the ground).
Every vehicle takes off to 3.5 m and hovers, streaming its default telemetry (to ports nobody
reads). Real-time factor = simulated s / CPU s of the measuring process at speed-up 0, each
measurement in a fresh process. `--baseline DIR` also measures the fleet of an older checkout
(e.g. `git worktree add /tmp/base <rev>`) in the same interleaved rounds. Run:
`PYTHONPATH=. python benchmarks/bench_fleet.py [--seconds 4] [--baseline DIR]`."""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sim.mavlink import Sitl, SitlConfig, SitlFleet
from sim.vehicle.fleet import KinematicFleet, QuadrotorFleet

#: CPU time of this process, not wall time: the machine is shared, and CPU time is what an idle
#: core would give (a wall clock here measures everyone else's load)
_clock = time.process_time


def _ports(k: int) -> list[int]:
    """k distinct free ports: every probe socket stays open until all are chosen (a port
    probed and closed at once can be handed out again, and a vehicle then fails to bind)."""
    socks = []
    try:
        for _ in range(k):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks.append(s)
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def _cfgs(n: int, physics: str, camera: bool = False) -> list[SitlConfig]:
    ports = iter(_ports(4 * n))
    return [SitlConfig(instance=i % 40, system_id=i + 1, speedup=0, physics=physics, camera=camera,
                       api_local_port=next(ports), api_remote_port=next(ports), gcs_local_port=next(ports),
                       gcs_remote_port=next(ports)) for i in range(n)]


def _take_off(sitls: list[Sitl]) -> None:
    for s in sitls:
        s.vehicle.arm()
        s.vehicle.takeoff(s.home.alt_m + 3.5)


def fleet(n: int, physics: str, seconds: float) -> float:
    f = SitlFleet(_cfgs(n, physics))
    _take_off(f.sitls)
    f.run(duration=1.0)  # warm up, leave the ground
    t0 = _clock()
    f.run(duration=1.0 + seconds)
    spent = _clock() - t0
    f.stop()
    return seconds / spent


#: simulated seconds between two frames of one vehicle's camera in `cameras`: 4 x what a search
#: asks (one frame per decision, SearchSpec.decision_period_s = 4 s), staggered over the fleet
FRAME_EVERY_S = 1.0


def cameras(n: int, physics: str, seconds: float) -> float:
    """The fleet with every vehicle's camera rendering a frame each FRAME_EVERY_S (its own
    PyBullet scene of the field and targets, sim/mavlink/sitl.py), as a fleet search would."""
    f = SitlFleet(_cfgs(n, physics, camera=True))
    _take_off(f.sitls)
    f.run(duration=1.0)
    ticks_per_frame = max(1, int(round(FRAME_EVERY_S / 0.02)))
    steps = int(round(seconds / 0.02))
    t0 = _clock()
    frames = 0
    for k in range(steps):
        f.step()
        for i in range(k % ticks_per_frame, n, ticks_per_frame):  # vehicle i's frame on its own tick
            f.sitls[i].render_now()
            frames += 1
    spent = _clock() - t0
    f.stop()
    if frames < n * (steps // ticks_per_frame):
        raise RuntimeError(f"cameras: {frames} frames for {n} vehicles over {seconds} s")
    return seconds / spent


def separate(n: int, physics: str, seconds: float) -> float:
    sitls = [Sitl(c) for c in _cfgs(n, physics)]
    _take_off(sitls)
    steps = int(round(seconds / 0.02))
    for _ in range(50):
        for s in sitls:
            s.step()
    t0 = _clock()
    for _ in range(steps):
        for s in sitls:
            s.step()
    spent = _clock() - t0
    for s in sitls:
        s.stop()
    return seconds / spent


def physics_only(n: int, physics: str, seconds: float) -> float:
    """physics "pybullet/K": only K of the n vehicles take off, the others stay disarmed on the
    ground (a fleet in PyBullet near the ground and in free flight in the air, sim/vehicle/fleet.py)."""
    physics, _, flying = physics.partition("/")
    k = int(flying) if flying else n
    w = QuadrotorFleet(n) if physics == "pybullet" else KinematicFleet(n)
    for m in w.members[:k]:
        m.arm()
        m.set_position_target(np.array([0.0, 0.0, -3.5]))
    for _ in range(50):
        w.step(0.02)
    t0 = _clock()
    for _ in range(int(round(seconds / 0.02))):
        w.step(0.02)
    spent = _clock() - t0
    w.close()
    return seconds / spent


RUNS = {"fleet": fleet, "separate": separate, "physics": physics_only, "cameras": cameras}


def _in_process(name: str, n: int, physics: str, seconds: float, baseline: Path | None) -> float:
    """One measurement in a fresh process, importing `sim` from this checkout or from `baseline`
    (an older checkout: the same benchmark code measures both, side by side)."""
    env = dict(os.environ)
    root = Path(__file__).resolve().parent.parent if baseline is None else baseline
    env["PYTHONPATH"] = str(root)
    out = subprocess.run([sys.executable, __file__, "--one", name, str(n), physics, str(seconds)], env=env,
                         capture_output=True, text=True, check=True).stdout
    return float(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated seconds per measurement")
    ap.add_argument("--rounds", type=int, default=2, help="interleaved rounds; the best of each is kept")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="a checkout of an older revision: its fleet is measured in the same rounds")
    ap.add_argument("--one", nargs=4, metavar=("RUN", "N", "PHYSICS", "SECONDS"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        name, n, physics, sec = args.one
        print(RUNS[name](int(n), physics, float(sec)))
        return
    if args.baseline is not None and not (args.baseline / "sim" / "mavlink").is_dir():
        raise SystemExit(f"--baseline {args.baseline}: not a checkout of this project (no sim/mavlink)")
    s = args.seconds
    loads = [os.getloadavg()[0]]
    print(f"load average {loads[0]:.2f} on {os.cpu_count()} cores; best of {args.rounds} interleaved "
          f"rounds of {s:.0f} simulated s, each in a fresh process; real-time factors by CPU time "
          "(goal >= 10x with MAVLink)")
    head = f"{'vehicles':<22}{'fleet':>10}{'separate':>10}{'fleet/sep':>11}{'physics only':>14}"
    print(head + (f"{'baseline fleet':>16}{'fleet/base':>12}" if args.baseline else ""))
    for n, physics in [(16, "pybullet"), (100, "kinematic")]:
        jobs = [(name, None) for name in RUNS if name != "cameras"] + ([("fleet", args.baseline)] if args.baseline else [])
        best = dict.fromkeys(jobs, 0.0)
        for _ in range(args.rounds):
            for name, base in jobs:
                best[name, base] = max(best[name, base], _in_process(name, n, physics, s, base))
                loads.append(os.getloadavg()[0])
        f, sep, ph = best["fleet", None], best["separate", None], best["physics", None]
        line = f"{f'{n} {physics}':<22}{f:>9.1f}x{sep:>9.1f}x{f / sep:>10.2f}x{ph:>13.1f}x"
        if args.baseline:
            b = best["fleet", args.baseline]
            line += f"{b:>15.1f}x{f / b:>11.2f}x"
        print(line, flush=True)
    # physics only, part of a PyBullet fleet flying: the rest on the ground, stepped by PyBullet
    print(f"{'physics only, 16 pybullet':<30}{'this checkout':>14}" + (f"{'baseline':>10}{'ratio':>8}" if args.baseline else ""))
    for k in (16, 12, 8, 1):
        jobs = [None] + ([args.baseline] if args.baseline else [])
        best = dict.fromkeys(jobs, 0.0)
        for _ in range(args.rounds):
            for base in jobs:
                best[base] = max(best[base], _in_process("physics", 16, f"pybullet/{k}", s, base))
                loads.append(os.getloadavg()[0])
        line = f"{f'  {k} flying, {16 - k} on the ground':<30}{best[None]:>13.1f}x"
        if args.baseline:
            line += f"{best[args.baseline]:>9.1f}x{best[None] / best[args.baseline]:>7.2f}x"
        print(line, flush=True)
    # cameras: every PyBullet vehicle renders its frames (goal: 4 at >= 20x, 16 at >= 10x)
    print(f"{'pybullet with cameras':<30}{'real time':>10}{'per vehicle vs 1':>18}   "
          f"(a {FRAME_EVERY_S:.0f} s frame per vehicle, 4x a search's)")
    sizes = (1, 4, 16)
    best = dict.fromkeys(sizes, 0.0)
    for _ in range(args.rounds):
        for n in sizes:
            best[n] = max(best[n], _in_process("cameras", n, "pybullet", s, None))
            loads.append(os.getloadavg()[0])
    for n in sizes:
        print(f"{f'  {n} vehicles':<30}{best[n]:>9.1f}x{best[n] * n / best[1]:>17.2f}x", flush=True)
    print(f"load average during the run: {min(loads):.1f}-{max(loads):.1f}"
          + (" (a loaded machine: CPU-time rates are noisy, compare the columns of one run)" if max(loads) > 2 else ""))


if __name__ == "__main__":
    main()
