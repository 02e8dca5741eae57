"""A thin MAVLink link to any vehicle (pymavlink), in the spirit of mavutil: one receive
thread keeps the latest telemetry and routes COMMAND_ACKs to whoever waits for them.

Commands block until the vehicle's ACK (with retries, as MAVSDK does) and raise
`CommandRejected` with the MAV_RESULT name when the vehicle says no, so a mission script
never mistakes a refusal for success.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink import mavutil

from . import px4_modes
from .tlog import CompanionTlog

mavlink = mavutil.mavlink
log = logging.getLogger(__name__)
STATUSTEXT_KEEP = 200  # the latest STATUSTEXTs kept in Telemetry (a chatty vehicle must not grow it)
_NET_ADDRESS = re.compile(r"^(udpin|udpout|udp|udpbcast|tcp|tcpin):([^:]+):(\d{1,5})$")


def check_address(address: str) -> None:
    """A clear error for an address pymavlink would misread (it opens anything else as a serial
    device): udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, or a serial device path."""
    if address.startswith("/dev/") or address.upper().startswith("COM"):
        return
    m = _NET_ADDRESS.match(address)
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise ValueError(f"bad MAVLink address {address!r}: expected udpin:HOST:PORT (listen, e.g. "
                         "udpin:0.0.0.0:14540), udpout:HOST:PORT, tcp:HOST:PORT or a serial device /dev/...")


@dataclass
class LinkStats:
    """What the link survived: the counts a lossy-link report shows."""

    received: int = 0
    rx_errors: int = 0  # exceptions raised while receiving or in a handler (the thread lives on)
    command_retries: int = 0
    foreign_datagrams: int = 0  # from addresses other than the vehicle's, dropped


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
    """The companion's link to one vehicle.

    Robust against a bad radio: the receive thread survives anything a message or a handler
    throws (counted in `stats.rx_errors` and logged); every command is resent with backoff until
    its ACK arrives, and a MAV_RESULT_IN_PROGRESS is waited on, not resent. Once the vehicle's
    first HEARTBEAT arrives, datagrams from any other address are dropped and nothing is sent
    anywhere else (pymavlink's udpin answers everyone who ever sent it a byte). The link speaks
    MAVLink 2 from the first packet, so a signing key is never lost in pymavlink's
    MAVLink 1 -> 2 switch. It sends its own HEARTBEAT (MAV_TYPE_ONBOARD_CONTROLLER) at 1 Hz,
    which the vehicle's data-link-loss failsafe watches.
    """

    def __init__(
        self,
        address: str = "udpin:0.0.0.0:14540",
        source_system: int = 245,
        source_component: int = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER,
        tlog: Path | None = None,
        signing_key: bytes | None = None,
        tlog_meta: dict | None = None,
        heartbeat_hz: float = 1.0,
    ) -> None:
        check_address(address)
        if signing_key is not None and len(signing_key) != 32:
            raise ValueError("a MAVLink2 signing key is 32 bytes")
        self.conn = mavutil.mavlink_connection(
            address, source_system=source_system, source_component=source_component
        )
        self._force_mavlink2(source_system, source_component)
        self.stats = LinkStats()
        self._vehicle_addr: tuple[str, int] | None = None
        self._last_addr: tuple[str, int] | None = None
        if isinstance(self.conn, mavutil.mavudp) and self.conn.udp_server:
            self.conn.recv = self._recv_udp  # only the vehicle we connected to, once we know it
        # both directions of the link, in MAVProxy's .tlog format (pymavlink's own logfile
        # stays empty on UDP connections)
        self.tlog = CompanionTlog(tlog, tlog_meta) if tlog is not None else None
        if self.tlog is not None:
            self.conn.mav.set_send_callback(self.tlog.write_message)
        if signing_key is not None:
            self.conn.setup_signing(signing_key, sign_outgoing=True)
        self.telemetry = Telemetry()
        self._acks: dict[int, int] = {}
        self._ack_cv = threading.Condition()
        self._send_lock = threading.Lock()  # pymavlink's MAVLink object is not thread-safe
        self._handlers: list = []
        self._stop = threading.Event()
        self._rx = threading.Thread(target=self._receive, name="mavlink-rx", daemon=True)
        self._rx.start()
        self._hb_period = 1.0 / heartbeat_hz if heartbeat_hz > 0 else 0.0
        self._hb = threading.Thread(target=self._heartbeats, name="mavlink-hb", daemon=True)
        if self._hb_period:
            self._hb.start()

    def _force_mavlink2(self, sysid: int, compid: int) -> None:
        """pymavlink starts a link in MAVLink 1 unless MAVLINK20 is set, and on the first v2
        packet replaces its MAVLink object, dropping the signing setup: start in v2."""
        from pymavlink.dialects.v20 import common as v20

        if self.conn.WIRE_PROTOCOL_VERSION != "2.0":
            self.conn.mav = v20.MAVLink(self.conn, srcSystem=sysid, srcComponent=compid)
            self.conn.mav.robust_parsing = True
            self.conn.WIRE_PROTOCOL_VERSION = "2.0"
        self.conn.first_byte = False

    def _recv_udp(self, n=None) -> bytes:
        sock = self.conn.port
        while True:
            try:
                data, addr = sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return b""
            except OSError:  # ECONNREFUSED and friends from an earlier send: not fatal
                return b""
            if self._vehicle_addr is not None and addr != self._vehicle_addr:
                self.stats.foreign_datagrams += 1
                continue
            if self._vehicle_addr is None:
                self.conn.clients.add(addr)
                self.conn.clients_last_alive[addr] = time.time()
            self._last_addr = addr
            return data

    def _lock_vehicle(self) -> None:
        """From now on, talk to the address the vehicle's heartbeat came from, and only to it."""
        addr = self._last_addr
        if self._vehicle_addr is not None or addr is None or not isinstance(self.conn, mavutil.mavudp):
            return
        self._vehicle_addr = addr
        self.conn.clients = {addr}
        self.conn.clients_last_alive = {addr: time.time()}
        log.info("link locked to the vehicle at %s:%d", *addr)

    # -- receiving -----------------------------------------------------------------------
    def add_handler(self, fn) -> None:
        """fn(msg) is called from the receive thread for every message."""
        self._handlers.append(fn)

    def _receive(self) -> None:
        """Never dies: whatever a message or a handler throws is counted, logged and survived."""
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.2)
                if msg is None or msg.get_type() == "BAD_DATA":
                    continue
                self.stats.received += 1
                if self.tlog is not None:
                    self.tlog.write_message(msg)
                self._on_message(msg)
            except Exception as e:  # noqa: BLE001 - a receive thread that dies is a silent link
                self._rx_error("receiving", e)
                time.sleep(0.01)
                continue
            for fn in list(self._handlers):
                try:
                    fn(msg)
                except Exception as e:  # noqa: BLE001
                    self._rx_error(f"handler {getattr(fn, '__qualname__', fn)}", e)

    def _rx_error(self, where: str, e: Exception) -> None:
        self.stats.rx_errors += 1
        n = self.stats.rx_errors
        if str(n).rstrip("0") == "1":  # the 1st, 10th, 100th ...: logged, never flooding
            log.warning("receive thread: %s raised %s: %s (%d errors so far)", where, type(e).__name__, e, n,
                        exc_info=n == 1)

    def _heartbeats(self) -> None:
        while not self._stop.wait(self._hb_period):
            try:
                with self._send_lock:
                    self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID,
                                                 0, 0, mavlink.MAV_STATE_ACTIVE)
            except Exception as e:  # noqa: BLE001 - a closed socket at shutdown
                if not self._stop.is_set():
                    log.warning("heartbeat send failed: %s", e)

    def _on_message(self, msg) -> None:
        t, kind = self.telemetry, msg.get_type()
        if kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
            self._lock_vehicle()
            t.heartbeat_time = time.monotonic()
            t.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            t.mode = px4_modes.decode(msg.custom_mode)
        elif kind == "COMMAND_ACK" and self.conn.target_component in (0, msg.get_srcComponent()):
            # the autopilot's (another component's, a camera's, is its sender's: camera/)
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
            del t.statustext[:-STATUSTEXT_KEEP]

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
    def command(self, cmd: int, *params: float, timeout: float = 0.5, retries: int = 10,
                progress_timeout: float = 30.0) -> int:
        """COMMAND_LONG, resent (confirmation + 1) with a growing wait until its ACK arrives;
        returns MAV_RESULT_ACCEPTED or raises CommandRejected / LinkError.

        An ACK answers any copy of the command, so a late one for an earlier copy counts.
        MAV_RESULT_IN_PROGRESS says the vehicle is working on it: we wait (up to
        `progress_timeout`) for the final ACK instead of resending."""
        p = list(params) + [0.0] * (7 - len(params))
        with self._ack_cv:
            self._acks.pop(cmd, None)
        wait = timeout
        for attempt in range(retries):
            if attempt:
                self.stats.command_retries += 1
            with self._send_lock:
                self.conn.mav.command_long_send(*self.target, cmd, min(attempt, 255), *p)
            end = time.monotonic() + wait
            with self._ack_cv:
                while True:
                    got = self._ack_cv.wait_for(lambda: cmd in self._acks, max(end - time.monotonic(), 0.0))
                    if not got:
                        break
                    result = self._acks.pop(cmd)
                    if result == mavlink.MAV_RESULT_IN_PROGRESS:
                        end = time.monotonic() + progress_timeout  # working on it: wait, do not resend
                        continue
                    if result != mavlink.MAV_RESULT_ACCEPTED:
                        raise CommandRejected(cmd, result)
                    return result
            wait = min(wait * 1.5, 3.0)
        raise LinkError(f"no COMMAND_ACK for command {cmd} after {retries} tries")

    def send_command_long(self, target: tuple[int, int], cmd: int, confirmation: int, *params: float) -> None:
        """One COMMAND_LONG to (system, component), not waited on: for another component of the
        vehicle (a camera), whose sender waits for that component's own ACK."""
        p = list(params) + [0.0] * (7 - len(params))
        with self._send_lock:
            self.conn.mav.command_long_send(*target, cmd, confirmation, *p)

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
        with self._send_lock:
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
        if self._hb.is_alive():
            self._hb.join(timeout=1.0)
        self.conn.close()
        if self.tlog is not None:
            self.tlog.close()

    def __enter__(self) -> VehicleLink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
