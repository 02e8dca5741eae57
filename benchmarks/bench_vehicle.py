"""Vehicle simulation speed, side by side in one run:
real-time factor of the headless quadrotor without and with the camera at 10 Hz, and frames
rendered per second at 50 x 50 vs 224 x 224."""

from __future__ import annotations

import time

import numpy as np

from sim.vehicle import DownCamera, Field, PyBulletQuadrotor, ViewRenderer, WorldState


def rtf(camera_hz: float, seconds: float = 20.0) -> float:
    q = PyBulletQuadrotor()
    cam = None
    if camera_hz:
        Field(q.cid, 10, 10, 5).set_targets(np.array([[1, 1], [2, 3], [5, 5], [7, 2], [8, 8]]))
        cam = DownCamera(q.cid)
    q.arm()
    q.set_position_target(np.array([0.0, 0.0, -3.5]))
    t0 = time.perf_counter()
    next_frame = 0.0
    while q.time < seconds:
        q.step(0.02)
        if cam is not None and q.time >= next_frame:
            cam.render(q.state.position_ned)
            next_frame += 1.0 / camera_hz
    wall = time.perf_counter() - t0
    q.close()
    return seconds / wall


def fps(size: int, frames: int) -> float:
    r = ViewRenderer(10, 10, 5, image=size)
    st = WorldState(10, 10, np.array([[1, 1], [2, 3], [5, 5], [7, 2], [8, 8]]))
    r.render_view(st, np.array([5, 5]))
    t0 = time.perf_counter()
    for i in range(frames):
        r.render_view(st, np.array([i % 10, (i // 10) % 10]))
    out = frames / (time.perf_counter() - t0)
    r.close()
    return out


def main() -> None:
    a, b = rtf(0), rtf(10)
    print(f"real-time factor, 240 Hz physics: no camera {a:.1f}x, camera at 10 Hz {b:.1f}x "
          f"(camera costs {100 * (1 - b / a):.0f} % of the speed)")
    f50, f224 = fps(50, 400), fps(224, 40)
    print(f"frames/s: 50x50 {f50:.0f}, 224x224 {f224:.0f} (ratio {f50 / f224:.1f}x)")


if __name__ == "__main__":
    main()
