"""A thin MAVLink link to any vehicle (pymavlink), in the spirit of mavutil: one receive
thread keeps the latest telemetry and routes COMMAND_ACKs to whoever waits for them.

Commands block until the vehicle's ACK (with retries, as MAVSDK does) and raise
`CommandRejected` with the MAV_RESULT name when the vehicle says no, so a mission script
never mistakes a refusal for success.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink import mavutil

from . import px4_modes
from .tlog import CompanionTlog

mavlink = mavutil.mavlink


class LinkError(RuntimeError):
    """The vehicle did not answer in time."""


class CommandRejected(RuntimeError):
    def __init__(self, command: int, result: int) -> None:
        self.command, self.result = command, result
        cname = mavlink.enums["MAV_CMD"].get(command)
        rname = mavlink.enums["MAV_RESULT"].get(result)
        super().__init__(
            f"{cname.name if cname else command} -> {rname.name if rname else result}"
        )


@dataclass
class Telemetry:
    """The latest of each message we use; times are this computer's monotonic clock."""

    heartbeat_time: float = 0.0
    armed: bool = False
    mode: str = ""
    landed_state: int = 0
    gps: dict = field(default_factory=dict)  # lat/lon deg, alt m, eph/epv m, fix_type, time_s
    position: dict = field(default_factory=dict)  # GLOBAL_POSITION_INT: lat, lon, relative_alt
    local: dict = field(default_factory=dict)  # LOCAL_POSITION_NED: n, e, d, vn, ve, vd
    home: dict = field(default_factory=dict)  # lat, lon, alt
    battery_remaining: float | None = None
    statustext: list[str] = field(default_factory=list)


class VehicleLink:
    def __init__(
        self,
        address: str = "udpin:0.0.0.0:14540",
        source_system: int = 245,
        source_component: int = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER,
        tlog: Path | None = None,
        signing_key: bytes | None = None,
        tlog_meta: dict | None = None,
    ) -> None:
        self.conn = mavutil.mavlink_connection(
            address, source_system=source_system, source_component=source_component
        )
        # both directions of the link, in MAVProxy's .tlog format (pymavlink's own logfile
        # stays empty on UDP connections)
        self.tlog = CompanionTlog(tlog, tlog_meta) if tlog is not None else None
        if self.tlog is not None:
            self.conn.mav.set_send_callback(self.tlog.write_message)
        if signing_key is not None:
            if len(signing_key) != 32:
                raise ValueError("a MAVLink2 signing key is 32 bytes")
            self.conn.setup_signing(signing_key, sign_outgoing=True)
        self.telemetry = Telemetry()
        self._acks: dict[int, int] = {}
        self._ack_cv = threading.Condition()
        self._handlers: list = []
        self._stop = threading.Event()
        self._rx = threading.Thread(target=self._receive, name="mavlink-rx", daemon=True)
        self._rx.start()

    # -- receiving -----------------------------------------------------------------------
    def add_handler(self, fn) -> None:
        """fn(msg) is called from the receive thread for every message."""
        self._handlers.append(fn)

    def _receive(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.2)
            except (OSError, ValueError):
                continue
            if msg is None or msg.get_type() == "BAD_DATA":
                continue
            if self.tlog is not None:
                self.tlog.write_message(msg)
            self._on_message(msg)
            for fn in list(self._handlers):
                fn(msg)

    def _on_message(self, msg) -> None:
        t, kind = self.telemetry, msg.get_type()
        if kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS:
            t.heartbeat_time = time.monotonic()
            t.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            t.mode = px4_modes.decode(msg.custom_mode)
        elif kind == "COMMAND_ACK":
            with self._ack_cv:
                self._acks[msg.command] = msg.result
                self._ack_cv.notify_all()
        elif kind == "GPS_RAW_INT":
            t.gps = {
                "lat": msg.lat * 1e-7, "lon": msg.lon * 1e-7, "alt": msg.alt * 1e-3,
                "eph": msg.h_acc * 1e-3 if getattr(msg, "h_acc", 0) else msg.eph * 1e-2,
                "epv": msg.v_acc * 1e-3 if getattr(msg, "v_acc", 0) else msg.epv * 1e-2,
                "fix_type": msg.fix_type, "satellites": msg.satellites_visible,
                "time_s": msg.time_usec * 1e-6,
            }
        elif kind == "GLOBAL_POSITION_INT":
            t.position = {
                "lat": msg.lat * 1e-7, "lon": msg.lon * 1e-7,
                "relative_alt": msg.relative_alt * 1e-3, "time_s": msg.time_boot_ms * 1e-3,
            }
        elif kind == "LOCAL_POSITION_NED":
            t.local = {"n": msg.x, "e": msg.y, "d": msg.z, "vn": msg.vx, "ve": msg.vy,
                       "vd": msg.vz, "time_s": msg.time_boot_ms * 1e-3}
        elif kind == "HOME_POSITION":
            t.home = {"lat": msg.latitude * 1e-7, "lon": msg.longitude * 1e-7, "alt": msg.altitude * 1e-3}
        elif kind == "EXTENDED_SYS_STATE":
            t.landed_state = msg.landed_state
        elif kind == "BATTERY_STATUS":
            t.battery_remaining = None if msg.battery_remaining < 0 else msg.battery_remaining / 100
        elif kind == "STATUSTEXT":
            t.statustext.append(msg.text)

    # -- waiting -------------------------------------------------------------------------
    def wait_for(self, predicate, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > end:
                raise LinkError(f"timed out after {timeout:.0f} s waiting for {what}")
            time.sleep(0.02)

    def wait_heartbeat(self, timeout: float = 10.0) -> None:
        self.wait_for(lambda: self.telemetry.heartbeat_time > 0, timeout, "a vehicle heartbeat")

    @property
    def target(self) -> tuple[int, int]:
        return self.conn.target_system or 1, self.conn.target_component or 1

    # -- commands ------------------------------------------------------------------------
    def command(self, cmd: int, *params: float, timeout: float = 1.0, retries: int = 3) -> int:
        """COMMAND_LONG with retries; returns MAV_RESULT_ACCEPTED or raises."""
        p = list(params) + [0.0] * (7 - len(params))
        for attempt in range(retries):
            with self._ack_cv:
                self._acks.pop(cmd, None)
            self.conn.mav.command_long_send(*self.target, cmd, attempt, *p)
            with self._ack_cv:
                got = self._ack_cv.wait_for(lambda: cmd in self._acks, timeout)
                if got:
                    result = self._acks.pop(cmd)
                    if result == mavlink.MAV_RESULT_IN_PROGRESS:
                        continue
                    if result != mavlink.MAV_RESULT_ACCEPTED:
                        raise CommandRejected(cmd, result)
                    return result
        raise LinkError(f"no COMMAND_ACK for command {cmd} after {retries} tries")

    def arm(self, force: bool = False) -> None:
        self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196 if force else 0)

    def disarm(self, force: bool = False) -> None:
        self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196 if force else 0)

    def set_mode(self, name: str) -> None:
        main, sub = px4_modes.encode(name)
        self.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub)

    def takeoff(self, altitude_m: float) -> None:
        nan = float("nan")
        self.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, altitude_m)

    def land(self) -> None:
        self.command(mavlink.MAV_CMD_NAV_LAND)

    def return_to_launch(self) -> None:
        self.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)

    def set_position_ned(self, n: float, e: float, d: float, yaw: float = float("nan")) -> None:
        """One SET_POSITION_TARGET_LOCAL_NED (position only); stream it for OFFBOARD."""
        ignore = (
            mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
        )
        if yaw != yaw:  # nan
            ignore |= mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
        self.conn.mav.set_position_target_local_ned_send(
            0, *self.target, mavlink.MAV_FRAME_LOCAL_NED, ignore, n, e, d, 0, 0, 0, 0, 0, 0,
            0 if yaw != yaw else yaw, 0,
        )

    def set_message_interval(self, msg_id: int, hz: float) -> None:
        self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz if hz > 0 else -1)

    def request_message(self, msg_id: int) -> None:
        self.command(mavlink.MAV_CMD_REQUEST_MESSAGE, msg_id)

    def close(self) -> None:
        self._stop.set()
        self._rx.join(timeout=1.0)
        self.conn.close()
        if self.tlog is not None:
            self.tlog.close()

    def __enter__(self) -> VehicleLink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
