"""MAVLink command round trip on loopback (COMMAND_LONG -> COMMAND_ACK through the SITL
vehicle), side by side with a raw UDP echo round trip on the same machine as the floor, and
the SITL's real-time factor with the kinematic vs the PyBullet airframe."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
from pymavlink import mavutil

from sim.mavlink import Sitl, SitlConfig

M = mavutil.mavlink


def udp_echo_rtt(n: int = 300) -> np.ndarray:
    srv = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    srv.bind(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    stop = threading.Event()

    def echo() -> None:
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                d, a = srv.recvfrom(2048)
                srv.sendto(d, a)
            except TimeoutError:
                continue

    th = threading.Thread(target=echo, daemon=True)
    th.start()
    c = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        c.sendto(b"x" * 41, ("127.0.0.1", port))
        c.recvfrom(2048)
        out.append(time.perf_counter() - t0)
    stop.set()
    th.join()
    return np.array(out)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ports() -> dict[str, int]:
    """OS-chosen ports, so the benchmark never meets a running `uavsearch sitl` or QGC."""
    return {k: _free_port() for k in ("api_local_port", "api_remote_port", "gcs_local_port", "gcs_remote_port")}


def command_rtt(n: int = 200) -> np.ndarray:
    sitl = Sitl(SitlConfig(instance=37, speedup=1.0, physics="kinematic", gcs_link=True, **_ports())).start()
    g = mavutil.mavlink_connection(f"udpin:0.0.0.0:{sitl.cfg.gcs_ports[1]}", source_system=255)
    g.wait_heartbeat(timeout=10)
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        g.mav.command_long_send(sitl.cfg.sysid, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 9999, 0, 0, 0, 0, 0, 0)
        while True:
            m = g.recv_match(type="COMMAND_ACK", blocking=True, timeout=2)
            if m is None or m.command == M.MAV_CMD_REQUEST_MESSAGE:
                break
        out.append(time.perf_counter() - t0)
    g.close()
    sitl.stop()
    return np.array(out)


def sitl_rtf(physics: str, seconds: float = 20.0) -> float:
    s = Sitl(SitlConfig(instance=38, speedup=0, physics=physics, camera=False, **_ports()))
    s.model.arm()  # hovering, so the controller runs every physics step
    s.model.set_position_target(np.array([0.0, 0.0, -3.5]))
    t0 = time.perf_counter()
    s.run(duration=seconds)
    wall = time.perf_counter() - t0
    s.stop()
    return seconds / wall


def main() -> None:
    echo, cmd = udp_echo_rtt(), command_rtt()
    p = lambda a, q: 1e3 * np.percentile(a, q)  # noqa: E731
    print(f"raw UDP echo      p50 {p(echo, 50):.3f} ms  p99 {p(echo, 99):.3f} ms")
    print(f"COMMAND_LONG->ACK p50 {p(cmd, 50):.3f} ms  p99 {p(cmd, 99):.3f} ms "
          f"({p(cmd, 50) / p(echo, 50):.1f}x the raw echo)")
    k, b = sitl_rtf("kinematic"), sitl_rtf("pybullet")
    print(f"SITL real-time factor (no camera): kinematic {k:.0f}x, pybullet {b:.0f}x (ratio {k / b:.1f})")


if __name__ == "__main__":
    main()
