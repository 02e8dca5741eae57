"""Failsafe timings (issue 12): for each failsafe, the wall-clock time from its cause to the
vehicle's reaction, beside the parameters that set it. Kinematic SITL, a pymavlink ground
station, speedup 4 (the battery drains on simulated time; the link timers run on wall time).

    nice -n 10 python benchmarks/bench_failsafes.py
"""

from __future__ import annotations

import math
import socket
import threading
import time
from pathlib import Path

from pymavlink import mavutil

from provenance import atomic_write_json, stamp
from sim.mavlink import Sitl, SitlConfig

M = mavutil.mavlink


def _port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _vehicle(params: dict[str, float]) -> tuple[Sitl, object]:
    sitl = Sitl(SitlConfig(instance=34, speedup=4.0, physics="kinematic", api_local_port=_port(),
                           api_remote_port=_port(), gcs_local_port=_port(), gcs_remote_port=_port())).start()
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{sitl.cfg.gcs_ports[1]}", source_system=255, source_component=190)
    c.wait_heartbeat(timeout=10)
    for name, value in params.items():
        sitl.vehicle.params.set(name, value)
    c.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
    sysid = sitl.cfg.sysid
    for cmd, p in ((M.MAV_CMD_COMPONENT_ARM_DISARM, [1]), (M.MAV_CMD_NAV_TAKEOFF, [0, 0, 0, math.nan, math.nan, math.nan, math.nan])):
        p = p + [0.0] * (7 - len(p))
        c.mav.command_long_send(sysid, 1, cmd, 0, *p)
        c.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
    end = time.monotonic() + 20
    while sitl.model.state.landed and time.monotonic() < end:
        time.sleep(0.05)
    time.sleep(1.0)
    return sitl, c


def _wait_mode(sitl: Sitl, modes: set[str], timeout: float) -> float | None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if sitl.vehicle.mode in modes:
            return time.monotonic() - t0
        time.sleep(0.01)
    return None


def offboard_loss() -> dict:
    sitl, c = _vehicle({"COM_OF_LOSS_T": 1.0, "COM_FAIL_ACT_T": 2.0})
    stop = threading.Event()

    def stream() -> None:
        while not stop.is_set():
            c.mav.set_position_target_local_ned_send(0, sitl.cfg.sysid, 1, M.MAV_FRAME_LOCAL_NED, 0b110111111000,
                                                     0, 0, -3.5, 0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.05)

    t = threading.Thread(target=stream)
    t.start()
    time.sleep(0.5)
    c.mav.command_long_send(sitl.cfg.sysid, 1, M.MAV_CMD_DO_SET_MODE, 0, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6,
                            0, 0, 0, 0, 0)
    time.sleep(0.5)
    stop.set()
    t.join()
    hold = _wait_mode(sitl, {"AUTO.LOITER"}, 10)
    action = _wait_mode(sitl, {"AUTO.RTL"}, 10)
    sitl.stop()
    return {"failsafe": "offboard loss", "params": "COM_OF_LOSS_T=1, COM_FAIL_ACT_T=2, COM_OBL_RC_ACT=0",
            "expected_s": "1 to hold, +2 to Return", "hold_s": hold, "action_s": None if action is None or hold is None
            else hold + action}


def datalink_loss() -> dict:
    sitl, c = _vehicle({"COM_DL_LOSS_T": 5.0})
    c.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)
    took = _wait_mode(sitl, {"AUTO.RTL"}, 15)
    sitl.stop()
    return {"failsafe": "data-link loss", "params": "COM_DL_LOSS_T=5, NAV_DLL_ACT=2", "expected_s": "5 to Return",
            "action_s": took}


def battery() -> dict:
    sitl, c = _vehicle({"UAVS_BAT_ENDUR_S": 60.0, "NAV_DLL_ACT": 0.0, "SIM_BAT_MIN_PCT": 0.0})  # no heartbeats here: DLL off
    t0, sim0 = time.monotonic(), sitl.t
    took = _wait_mode(sitl, {"AUTO.RTL"}, 60)
    r = sitl.vehicle.battery.remaining
    log = list(sitl.vehicle.failsafe_log)
    sitl.stop()
    return {"failsafe": "battery critical", "params": "UAVS_BAT_ENDUR_S=60, BAT_CRIT_THR=0.07, COM_LOW_BAT_ACT=3",
            "expected_s": "about 55.8 simulated s of hover from full (~14 wall s at speedup 4)", "action_s": took,
            "simulated_s": round(log[-1][0] - sim0, 1) if log else None, "remaining_at_action": round(r, 3),
            "wall_from_start_s": round(time.monotonic() - t0, 1)}


def main() -> None:
    rows = [offboard_loss(), datalink_loss(), battery()]
    for r in rows:
        print(r, flush=True)
    atomic_write_json(Path("results/failsafe_timings.json"), stamp({"speedup": 4.0}, 0, kind="failsafe timings", rows=rows))


if __name__ == "__main__":
    main()
