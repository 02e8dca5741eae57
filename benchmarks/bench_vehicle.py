"""Vehicle simulation speed, side by side in one run (issue 13):
- a bare `stepSimulation` loop of the same body (the physics limit), resting on the ground as
  it is spawned, and floating in the air with gravity off (no contacts: the cheapest step);
- the quadrotor flown by the original numpy maths (tests/sim/vehicle/reference_quadrotor.py);
- the quadrotor as shipped, without the camera and with the camera at 10 Hz;
and frames rendered per second at 50 x 50 vs 224 x 224.

Real-time factors are simulated seconds per CPU second of this process at 240 Hz physics. Run:
`PYTHONPATH=. python benchmarks/bench_vehicle.py [--seconds 20]`.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import pybullet as p

from sim.vehicle import DownCamera, Field, PyBulletQuadrotor, ViewRenderer, WorldState
from sim.vehicle.quadrotor import PHYSICS_HZ

TARGETS = np.array([[1, 1], [2, 3], [5, 5], [7, 2], [8, 8]])

#: CPU time of this process, not wall time: the machine is shared, and CPU time is what an idle
#: core would give (a wall clock here measures everyone else's load)
_clock = time.process_time


def bare(seconds: float, floating: bool) -> float:
    """Real-time factor of stepSimulation alone on the quadrotor's world and body."""
    q = PyBulletQuadrotor()
    if floating:
        p.setGravity(0, 0, 0, physicsClientId=q.cid)
        p.resetBasePositionAndOrientation(q.body, [0, 0, 3.5], [0, 0, 0, 1], physicsClientId=q.cid)
    n = int(seconds * PHYSICS_HZ)
    t0 = _clock()
    for _ in range(n):
        p.stepSimulation(physicsClientId=q.cid)
    spent = _clock() - t0
    q.close()
    return seconds / spent


def rtf(camera_hz: float, seconds: float, model: type = PyBulletQuadrotor) -> float:
    """Take off to 3.5 m and fly a square; the camera (if any) renders the field at camera_hz."""
    q = model()
    cam = None
    if camera_hz:
        Field(q.cid, 10, 10, 5).set_targets(TARGETS)
        cam = DownCamera(q.cid)
    q.arm()
    q.set_position_target(np.array([0.0, 0.0, -3.5]))
    corners = [(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (0.0, 6.0)]
    t0 = _clock()
    next_frame, leg = 0.0, 0
    while q.time < seconds:
        q.step(0.02)
        if q.time > 4.0 + 4.0 * leg:  # a new corner every 4 s after the climb
            n, e = corners[leg % 4]
            q.set_position_target(np.array([n, e, -3.5]), speed=3.0)
            leg += 1
        if cam is not None and q.time >= next_frame:
            cam.render(q.state.position_ned)
            next_frame += 1.0 / camera_hz
    spent = _clock() - t0
    q.close()
    return seconds / spent


def fps(size: int, frames: int) -> float:
    r = ViewRenderer(10, 10, 5, image=size)
    st = WorldState(10, 10, TARGETS)
    r.render_view(st, np.array([5, 5]))
    t0 = _clock()
    for i in range(frames):
        r.render_view(st, np.array([i % 10, (i // 10) % 10]))
    out = frames / (_clock() - t0)
    r.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per measurement")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds; the best of each is kept")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "sim" / "vehicle"))
    from reference_quadrotor import ReferenceQuadrotor

    s = args.seconds
    runs = {
        "bare stepSimulation, body on the ground": lambda: bare(s, False),
        "bare stepSimulation, body floating": lambda: bare(s, True),
        "vehicle, original numpy maths": lambda: rtf(0, s, ReferenceQuadrotor),
        "vehicle, no camera": lambda: rtf(0, s),
        "vehicle, camera at 10 Hz": lambda: rtf(10, s),
    }
    # the machine is shared: interleave the runs and keep each one's best round, so a burst of
    # someone else's load does not land on one side of a ratio only
    best = dict.fromkeys(runs, 0.0)
    load0 = os.getloadavg()[0]
    for _ in range(args.rounds):
        for name, run in runs.items():
            best[name] = max(best[name], run())
    print(f"load average {load0:.2f} -> {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; "
          f"best of {args.rounds} interleaved rounds of {s:.0f} simulated s")
    print("real-time factor, 240 Hz physics:")
    goals = {"vehicle, no camera": "  (goal >= 100x)", "vehicle, camera at 10 Hz": "  (goal >= 50x)"}
    for name, x in best.items():
        print(f"  {name:<42}{x:7.1f}x{goals.get(name, '')}")
    ground, air = best["bare stepSimulation, body on the ground"], best["bare stepSimulation, body floating"]
    a, b, old = best["vehicle, no camera"], best["vehicle, camera at 10 Hz"], best["vehicle, original numpy maths"]
    print(f"ratios: vehicle / bare on the ground {a / ground:.2f} (goal >= 0.4), / bare floating {a / air:.2f}; "
          f"speed-up over the original maths {a / old:.1f}x; camera costs {100 * (1 - b / a):.0f} % of the speed")
    f50, f224 = fps(50, 400), fps(224, 40)
    print(f"frames/s: 50x50 {f50:.0f}, 224x224 {f224:.0f} (ratio {f50 / f224:.1f}x)")


if __name__ == "__main__":
    main()
