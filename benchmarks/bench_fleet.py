"""Many vehicles in one process (issue 13), side by side in one run:
- the fleet (`uavsearch sitl --count N`): one physics step and one vectorised controller for
  all vehicles, then each vehicle's MAVLink tick;
- the same N vehicles as N separate `Sitl` objects stepped one after the other (a Python loop
  per vehicle, each with its own physics world), as `--count N` ran before;
- the fleet's physics alone (no MAVLink endpoints).
Every vehicle takes off to 3.5 m and hovers, streaming its default telemetry (to ports nobody
reads). Real-time factor = simulated s / CPU s of this process at speed-up 0. Run:
`PYTHONPATH=. python benchmarks/bench_fleet.py [--seconds 4]`."""

from __future__ import annotations

import argparse
import os
import socket
import time

import numpy as np

from sim.mavlink import Sitl, SitlConfig, SitlFleet
from sim.vehicle.fleet import KinematicFleet, QuadrotorFleet

#: CPU time of this process, not wall time: the machine is shared, and CPU time is what an idle
#: core would give (a wall clock here measures everyone else's load)
_clock = time.process_time


def _port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cfgs(n: int, physics: str) -> list[SitlConfig]:
    return [SitlConfig(instance=i % 40, system_id=i + 1, speedup=0, physics=physics, camera=False,
                       api_local_port=_port(), api_remote_port=_port(), gcs_local_port=_port(),
                       gcs_remote_port=_port()) for i in range(n)]


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
    w = QuadrotorFleet(n) if physics == "pybullet" else KinematicFleet(n)
    for m in w.members:
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated seconds per measurement")
    ap.add_argument("--rounds", type=int, default=2, help="interleaved rounds; the best of each is kept")
    args = ap.parse_args()
    s = args.seconds
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; best of {args.rounds} interleaved "
          f"rounds of {s:.0f} simulated s; real-time factors (goal >= 10x with MAVLink)")
    print(f"{'vehicles':<22}{'fleet':>10}{'separate':>10}{'fleet/sep':>11}{'physics only':>14}")
    for n, physics in [(16, "pybullet"), (100, "kinematic")]:
        runs = {"fleet": fleet, "separate": separate, "physics": physics_only}
        best = dict.fromkeys(runs, 0.0)
        for _ in range(args.rounds):
            for name, run in runs.items():
                best[name] = max(best[name], run(n, physics, s))
        print(f"{f'{n} {physics}':<22}{best['fleet']:>9.1f}x{best['separate']:>9.1f}x"
              f"{best['fleet'] / best['separate']:>10.2f}x{best['physics']:>13.1f}x")


if __name__ == "__main__":
    main()
