"""A short flight, with plain pymavlink, of a real autopilot on our body: the measurement that
says the bridge works (take-off, 2 m position legs, hover accuracy, landing, clock relation).

  PYTHONPATH=. python -m sim.bridges.flight_check --autopilot px4 --instance 20 --speedup 5

ArduPilot: GUIDED (custom mode 4), arm, MAV_CMD_NAV_TAKEOFF, SET_POSITION_TARGET_LOCAL_NED
legs, LAND (mode 9), wait for the disarm. PX4: setpoints streamed first, OFFBOARD (custom
main mode 6), arm, climb by setpoint, the same legs, MAV_CMD_NAV_LAND, wait for the disarm.
Settle time of a leg: from the setpoint's sending to the first estimate within `tolerance_m`
(3D), on the autopilot's clock (LOCAL_POSITION_NED.time_boot_ms). Hover accuracy: the
estimate's distance from the setpoint over the last second of each hold; beside it the true
body's distance from the estimate (the estimator's error: mostly the GPS receiver's bias).
"""

from __future__ import annotations

import argparse
import json
import math
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any

from pymavlink import mavutil

TYPE_MASK_POSITION = 3576  # position only: ignore velocity, acceleration, yaw, yaw rate
PX4_OFFBOARD = 6
COPTER_GUIDED, COPTER_LAND = 4, 9


class FlightCheckError(RuntimeError):
    pass


@dataclass
class Leg:
    target_ned: tuple[float, float, float]
    settle_s: float | None  # None: never within tolerance during the hold
    hold_err_mean_m: float | None = None  # the autopilot's estimate vs setpoint, last second of the hold
    hold_err_max_m: float | None = None
    #: the true body vs the estimate over the same second: the estimator's error (GPS bias)
    est_err_mean_m: float | None = None


@dataclass
class FlightReport:
    autopilot: str
    ready_s: float = math.nan  # autopilot clock when ready to arm
    takeoff_s: float | None = None  # from the take-off command to within tolerance of 3.5 m
    legs: list[Leg] = field(default_factory=list)
    landed_disarmed: bool = False
    land_s: float | None = None
    wall_s: float = math.nan
    sim_s: float = math.nan
    clock: dict[str, float] = field(default_factory=dict)  # autopilot clock - world clock (s)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class Link:
    """The companion's end: messages kept by type, the world's time at their arrival noted."""

    def __init__(self, address: str, world_time=None, source_system: int = 245) -> None:
        self.m = mavutil.mavlink_connection(address, source_system=source_system, source_component=190,
                                            autoreconnect=True)
        self.world_time = world_time
        self.last: dict[str, Any] = {}
        self.clock_offsets: list[float] = []  # time_boot_ms/1e3 - world t at arrival
        self.gps_offsets: list[float] = []  # GPS_RAW_INT.time_usec/1e6 - world t at arrival
        self.target_system = 1
        self._hb_wall = 0.0

    def pump(self, timeout: float = 0.05) -> None:
        if time.monotonic() - self._hb_wall > 0.5:  # a companion's heartbeat (and PX4 > 9 learns our port)
            self._hb_wall = time.monotonic()
            self.m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                                      mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        msg = self.m.recv_match(blocking=True, timeout=timeout)
        while msg is not None:
            kind = msg.get_type()
            if kind != "BAD_DATA" and msg.get_srcComponent() == 1:
                self.last[kind] = msg
                self.target_system = msg.get_srcSystem()
                if self.world_time is not None:
                    t = self.world_time()
                    if hasattr(msg, "time_boot_ms"):
                        self.clock_offsets.append(msg.time_boot_ms / 1e3 - t)
                    if kind == "GPS_RAW_INT":
                        self.gps_offsets.append(msg.time_usec / 1e6 - t)
            msg = self.m.recv_match(blocking=False)

    def wait(self, what: str, cond, timeout: float) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.pump()
            if cond():
                return
        raise FlightCheckError(f"timed out after {timeout:g} s waiting for {what}; last "
                               f"{ {k: v.to_dict() for k, v in self.last.items() if k in ('HEARTBEAT', 'EKF_STATUS_REPORT', 'SYS_STATUS', 'LOCAL_POSITION_NED', 'STATUSTEXT')} }")

    def command(self, cmd: int, *params: float) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.m.mav.command_long_send(self.target_system, 1, cmd, 0, *p)

    def interval(self, msg_id: int, hz: float) -> None:
        self.command(mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)

    def setpoint(self, n: float, e: float, d: float) -> None:
        self.m.mav.set_position_target_local_ned_send(0, self.target_system, 1, mavutil.mavlink.MAV_FRAME_LOCAL_NED,
                                                      TYPE_MASK_POSITION, n, e, d, 0, 0, 0, 0, 0, 0, 0, 0)

    @property
    def armed(self) -> bool:
        hb = self.last.get("HEARTBEAT")
        return hb is not None and bool(hb.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    @property
    def boot_s(self) -> float:
        lp = self.last.get("LOCAL_POSITION_NED") or self.last.get("ATTITUDE")
        return math.nan if lp is None else lp.time_boot_ms / 1e3

    def position(self) -> tuple[float, float, float] | None:
        lp = self.last.get("LOCAL_POSITION_NED")
        return None if lp is None else (lp.x, lp.y, lp.z)

    def close(self) -> None:
        self.m.close()


def _dist(a, b) -> float:
    return math.dist(a, b)


def fly(link: Link, autopilot: str, truth=None, altitude: float = 3.5, leg_m: float = 2.0,
        hold_s: float = 4.0, tolerance_m: float = 0.5, ready_timeout: float = 120.0,
        speedup: float = 1.0) -> FlightReport:
    """Fly the check; truth(): the true body NED (for hover accuracy), or None."""
    rep = FlightReport(autopilot)
    wall0 = time.monotonic()
    k = 1.0 / max(speedup, 1e-3)  # wall seconds per simulated second, for timeouts
    link.wait("a heartbeat", lambda: "HEARTBEAT" in link.last, 60)
    ml = mavutil.mavlink
    for msg_id, hz in ((ml.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 20), (ml.MAVLINK_MSG_ID_ATTITUDE, 10),
                       (ml.MAVLINK_MSG_ID_GPS_RAW_INT, 5), (ml.MAVLINK_MSG_ID_SYS_STATUS, 2),
                       (ml.MAVLINK_MSG_ID_EKF_STATUS_REPORT, 2), (ml.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 2)):
        link.interval(msg_id, hz)
    if autopilot == "ardupilot":
        def ready() -> bool:
            ekf = link.last.get("EKF_STATUS_REPORT")
            return ekf is not None and bool(ekf.flags & 16) and not ekf.flags & 128 and "GPS_RAW_INT" in link.last \
                and link.last["GPS_RAW_INT"].fix_type >= 3
    else:
        def ready() -> bool:
            ss, gps = link.last.get("SYS_STATUS"), link.last.get("GPS_RAW_INT")
            return (ss is not None and bool(ss.onboard_control_sensors_health & ml.MAV_SYS_STATUS_PREARM_CHECK)
                    and gps is not None and gps.fix_type >= 3 and "LOCAL_POSITION_NED" in link.last)
    link.wait("ready to arm", ready, ready_timeout)
    rep.ready_s = link.boot_s
    home = link.position() or (0.0, 0.0, 0.0)
    target = [home[0], home[1], -altitude]
    stream_stop = threading.Event()
    streamer = None
    if autopilot == "px4":  # OFFBOARD wants setpoints streaming before and all the while
        def stream() -> None:
            while not stream_stop.is_set():
                link.setpoint(*target)
                stream_stop.wait(0.05)

        streamer = threading.Thread(target=stream, daemon=True)
        streamer.start()
    try:
        armed_at = None
        for _attempt in range(20):
            if autopilot == "ardupilot":
                link.m.mav.set_mode_send(link.target_system, ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, COPTER_GUIDED)
            else:
                link.wait("setpoints streamed", lambda: True, 1.5 * k + 0.2)
                link.command(ml.MAV_CMD_DO_SET_MODE, ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, PX4_OFFBOARD)
            link.wait("mode", lambda: True, 0.5 * k + 0.1)
            link.command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            try:
                link.wait("armed", lambda: link.armed, 2 * k + 0.5)
                armed_at = link.boot_s
                break
            except FlightCheckError:
                continue
        if armed_at is None:
            raise FlightCheckError(f"{autopilot} did not arm: {link.last.get('STATUSTEXT')}")
        if autopilot == "ardupilot":
            link.command(ml.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, altitude)
        t_cmd = link.boot_s

        def near(tgt) -> bool:
            pos = link.position()
            return pos is not None and _dist(pos, tgt) < tolerance_m

        link.wait("take-off height", lambda: near(target), 30 * k + 5)
        rep.takeoff_s = link.boot_s - t_cmd
        link.wait("hover", lambda: link.boot_s - t_cmd > rep.takeoff_s + 2.0, 10 * k + 5)
        for dn, de in ((leg_m, 0.0), (0.0, leg_m), (-leg_m, 0.0), (0.0, -leg_m)):
            target = [target[0] + dn, target[1] + de, target[2]]
            if autopilot == "ardupilot":
                link.setpoint(*target)
            t0 = link.boot_s
            settle = None
            errs: list[float] = []
            est: list[float] = []
            while link.boot_s - t0 < hold_s:
                link.pump()
                if settle is None and near(target):
                    settle = link.boot_s - t0
                pos = link.position()
                if pos is not None and link.boot_s - t0 > hold_s - 1.0:
                    errs.append(_dist(pos, target))
                    if truth is not None:
                        est.append(_dist(truth(), pos))
                if time.monotonic() - wall0 > 600:
                    raise FlightCheckError("flight check ran over 600 s of wall time")
            rep.legs.append(Leg(tuple(target), settle, sum(errs) / len(errs) if errs else None,
                                max(errs) if errs else None, sum(est) / len(est) if est else None))
        t_land = link.boot_s
        stream_stop.set()
        if autopilot == "ardupilot":
            link.m.mav.set_mode_send(link.target_system, ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, COPTER_LAND)
        else:
            link.command(ml.MAV_CMD_NAV_LAND, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
        link.wait("landed and disarmed", lambda: not link.armed, 60 * k + 10)
        rep.landed_disarmed = True
        rep.land_s = link.boot_s - t_land
    finally:
        stream_stop.set()
        if streamer is not None:
            streamer.join(timeout=1)
    rep.wall_s = time.monotonic() - wall0
    rep.sim_s = link.boot_s
    if link.clock_offsets:
        rep.clock["time_boot_minus_world_min_s"] = min(link.clock_offsets)
        rep.clock["time_boot_minus_world_max_s"] = max(link.clock_offsets)
    if link.gps_offsets:
        rep.clock["gps_time_usec_minus_world_min_s"] = min(link.gps_offsets)
        rep.clock["gps_time_usec_minus_world_max_s"] = max(link.gps_offsets)
    return rep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--autopilot", choices=("ardupilot", "px4"), required=True)
    ap.add_argument("--instance", type=int, default=20)
    ap.add_argument("--speedup", type=float, default=5.0)
    ap.add_argument("--bin", default=None)
    ap.add_argument("--keep-dir", action="store_true")
    a = ap.parse_args()
    from .world import AutopilotWorld, AutopilotWorldConfig

    cfg = AutopilotWorldConfig(autopilot=a.autopilot, instance=a.instance, speedup=a.speedup, binary=a.bin,
                               keep_dir=a.keep_dir, camera=False)
    with AutopilotWorld(cfg) as world:
        world.wait_physics()
        link = Link(world.companion_address(), lambda: world.t)
        try:
            rep = fly(link, a.autopilot, truth=lambda: tuple(world.body.state.position_ned), speedup=a.speedup)
        finally:
            link.close()
        out = rep.to_dict()
        out["world"] = world.stats()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
