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
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink import mavutil

from .dialects import Dialect, by_name, for_autopilot
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


#: wall seconds without a single message from the other end after which a command's resends
#: stop: a cut radio otherwise cost the 10 tries' ~22 s of growing waits before the companion
#: said so (a lossy link still delivers most of its 10-30 Hz telemetry: never this silent)
SILENT_GIVE_UP_S = 5.0


def resend_until_acked(send: Callable[[int], None], cv: threading.Condition, acks: dict[int, int], cmd: int,
                       timeout: float, retries: int, progress_timeout: float,
                       silent_for: Callable[[], float]) -> tuple[int | None, int]:
    """A COMMAND_LONG sent as send(confirmation) and resent with a growing wait until its ACK
    lands in acks[cmd] (filled under cv by a receive thread). An ACK answers any copy, so a late
    one for an earlier copy counts; MAV_RESULT_IN_PROGRESS waits (up to progress_timeout) for
    the final ACK instead of resending. Gives up after `retries` tries, or sooner once nothing at
    all has come from the other end for SILENT_GIVE_UP_S. Returns (the final result or None,
    the tries made)."""
    with cv:
        acks.pop(cmd, None)
    wait = timeout
    for attempt in range(retries):
        send(min(attempt, 255))
        end = time.monotonic() + wait
        with cv:
            while True:
                if not cv.wait_for(lambda: cmd in acks, max(end - time.monotonic(), 0.0)):
                    break
                result = acks.pop(cmd)
                if result == mavlink.MAV_RESULT_IN_PROGRESS:
                    end = time.monotonic() + progress_timeout  # working on it: wait, do not resend
                    continue
                return result, attempt + 1
        if silent_for() > SILENT_GIVE_UP_S:
            return None, attempt + 1
        wait = min(wait * 1.5, 3.0)
    return None, retries


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
    """The vehicle said no; `reason` is what it said alongside (ArduPilot's STATUSTEXT
    "PreArm: ..."), so the operator reads one line that says why."""

    def __init__(self, command: int, result: int, reason: str = "") -> None:
        self.command, self.result, self.reason = command, result, reason
        cname = mavlink.enums["MAV_CMD"].get(command)
        rname = mavlink.enums["MAV_RESULT"].get(result)
        super().__init__(
            f"{cname.name if cname else command} -> {rname.name if rname else result}"
            + (f" ({reason})" if reason else "")
        )


class WrongAutopilot(LinkError):
    """The vehicle's HEARTBEAT names another autopilot family than the one asked for."""


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
    #: (monotonic time, severity, text) of the latest STATUSTEXTs, for refusals' reasons
    statustext_log: list[tuple[float, int, str]] = field(default_factory=list)
    autopilot: int | None = None  # HEARTBEAT.autopilot of the vehicle
    ekf_flags: int | None = None  # EKF_STATUS_REPORT.flags (ArduPilot)
    #: SYS_STATUS onboard_control_sensors_present / _health (PX4's pre-arm check bit among them)
    sensors_present: int = 0
    sensors_health: int = 0
    #: GPS_GLOBAL_ORIGIN: the local frame's origin (lat, lon, alt), where the autopilot says it
    local_origin: dict = field(default_factory=dict)


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
        dialect: str | Dialect = "auto",
    ) -> None:
        check_address(address)
        #: the autopilot family's dialect: given, or taken from the first autopilot HEARTBEAT
        self.dialect: Dialect | None = by_name(dialect) if isinstance(dialect, str) and dialect != "auto" else (
            None if isinstance(dialect, str) else dialect)
        self._dialect_asked = self.dialect
        self.dialect_mismatch: str | None = None
        self._autopilot_id: tuple[int, int] | None = None  # (system, component) of the autopilot
        self._params: dict[str, tuple[float, int]] = {}  # PARAM_VALUE by name: (raw value, type)
        self._param_cv = threading.Condition()
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
        self._last_received = time.monotonic()  # nothing yet: counted from the link's opening
        self._stop = threading.Event()
        self.heartbeats_silenced = False
        #: (this computer's monotonic s, the vehicle's boot s) of recent telemetry, for its clock rate
        #: (before the receive thread starts: a vehicle already streaming when the link opens, as a
        #: fleet's, raised AttributeError in its first messages' handler)
        self._boot_clock: deque[tuple[float, float]] = deque(maxlen=64)
        self._rx = threading.Thread(target=self._receive, name="mavlink-rx", daemon=True)
        self._rx.start()
        self._hb_period = 1.0 / heartbeat_hz if heartbeat_hz > 0 else 0.0
        self._hb = threading.Thread(target=self._heartbeats, name="mavlink-hb", daemon=True)
        if self._hb_period:
            self._hb.start()

    def _force_mavlink2(self, sysid: int, compid: int) -> None:
        """pymavlink starts a link in MAVLink 1 unless MAVLINK20 is set, and on the first v2
        packet replaces its MAVLink object, dropping the signing setup: start in v2."""
        from pymavlink.dialects.v20 import ardupilotmega as v20

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

    def remove_handler(self, fn) -> None:
        """Stop calling fn (a transfer's queue, fence.py, once it is done)."""
        if fn in self._handlers:
            self._handlers.remove(fn)

    def send_message(self, msg) -> None:
        """Send one message the caller built with `conn.mav.*_encode` (the mission protocol's,
        fence.py), under the lock every sender here takes."""
        with self._send_lock:
            self.conn.mav.send(msg)

    def _receive(self) -> None:
        """Never dies: whatever a message or a handler throws is counted, logged and survived."""
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.2)
                if msg is None or msg.get_type() == "BAD_DATA":
                    continue
                self.stats.received += 1
                self._last_received = time.monotonic()
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

    def silence_heartbeats(self, silent: bool) -> None:
        """Stop (or resume) this companion's HEARTBEATs: where the autopilot's companion-loss
        failsafe watches them (ArduPilot's GCS failsafe), a hung decision loop must fall silent
        for the failsafe to take over, as a dead process does."""
        self.heartbeats_silenced = silent

    def vehicle_clock_rate(self) -> float:
        """How fast the vehicle's clock runs against this computer's (its telemetry's
        time_boot_ms over the last few seconds; 1 until measured): a SITL faster than real time
        counts its failsafe timeouts in its own seconds."""
        clock = list(self._boot_clock)
        if len(clock) < 2 or clock[-1][0] - clock[0][0] < 1.0:
            return 1.0
        (m0, b0), (m1, b1) = clock[0], clock[-1]
        return max((b1 - b0) / (m1 - m0), 0.0)

    def heartbeat_now(self) -> None:
        """One HEARTBEAT at once (after SYSID_MYGCS names this companion: ArduPilot's GCS
        failsafe is armed only once it has heard the system it watches)."""
        with self._send_lock:
            self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID,
                                         0, 0, mavlink.MAV_STATE_ACTIVE)

    def _heartbeats(self) -> None:
        """At heartbeat_hz of the vehicle's clock (at most 20 Hz of ours): a SITL at 10x with
        FS_GCS_TIMEOUT 5 s would otherwise see a 1 Hz companion silent for 10 of its seconds."""
        while not self._stop.wait(max(self._hb_period / max(self.vehicle_clock_rate(), 1.0), 0.05)):
            if self.heartbeats_silenced:
                continue
            try:
                self.heartbeat_now()
            except Exception as e:  # noqa: BLE001 - a closed socket at shutdown
                if not self._stop.is_set():
                    log.warning("heartbeat send failed: %s", e)

    def _on_message(self, msg) -> None:
        t, kind = self.telemetry, msg.get_type()
        if kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
            self._lock_vehicle()
            if self._autopilot_id is None:
                self._autopilot_id = (msg.get_srcSystem(), msg.get_srcComponent())
                self._choose_dialect(msg.autopilot)
            t.heartbeat_time = time.monotonic()
            t.autopilot = msg.autopilot
            t.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            if self.dialect is not None:
                t.mode = self.dialect.decode_mode(msg.custom_mode)
        elif kind == "COMMAND_ACK" and (self._autopilot_id is None or msg.get_srcComponent() == self._autopilot_id[1]):
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
            now = time.monotonic()
            if not self._boot_clock or now - self._boot_clock[-1][0] > 0.1:
                self._boot_clock.append((now, msg.time_boot_ms * 1e-3))
            while len(self._boot_clock) > 2 and now - self._boot_clock[1][0] > 3.0:
                self._boot_clock.popleft()
            t.local = {"n": msg.x, "e": msg.y, "d": msg.z, "vn": msg.vx, "ve": msg.vy,
                       "vd": msg.vz, "time_s": msg.time_boot_ms * 1e-3}
        elif kind == "HOME_POSITION":
            # x, y, z: home in the local frame (PX4: where its EKF put home, so origin = home
            # less these; ArduPilot sends zeros and streams GPS_GLOBAL_ORIGIN instead)
            t.home = {"lat": msg.latitude * 1e-7, "lon": msg.longitude * 1e-7, "alt": msg.altitude * 1e-3,
                      "x": msg.x, "y": msg.y, "z": msg.z}
        elif kind == "EXTENDED_SYS_STATE":
            t.landed_state = msg.landed_state
        elif kind == "BATTERY_STATUS":
            t.battery_remaining = None if msg.battery_remaining < 0 else msg.battery_remaining / 100
        elif kind == "STATUSTEXT":
            t.statustext.append(msg.text)
            del t.statustext[:-STATUSTEXT_KEEP]
            t.statustext_log.append((time.monotonic(), msg.severity, msg.text))
            del t.statustext_log[:-STATUSTEXT_KEEP]
        elif kind == "SYS_STATUS":
            t.sensors_present, t.sensors_health = msg.onboard_control_sensors_present, msg.onboard_control_sensors_health
        elif kind == "EKF_STATUS_REPORT":
            t.ekf_flags = msg.flags
        elif kind == "GPS_GLOBAL_ORIGIN":
            t.local_origin = {"lat": msg.latitude * 1e-7, "lon": msg.longitude * 1e-7, "alt": msg.altitude * 1e-3}
        elif kind == "PARAM_VALUE":
            with self._param_cv:
                self._params[msg.param_id] = (msg.param_value, msg.param_type)
                self._param_cv.notify_all()

    def _choose_dialect(self, autopilot: int) -> None:
        """The family from the first autopilot HEARTBEAT; a family other than the one asked for
        is remembered as a mismatch that wait_heartbeat reports."""
        found = for_autopilot(autopilot)
        if self.dialect is None:
            self.dialect = found
            if found is None:
                self.dialect_mismatch = (f"the vehicle's autopilot (MAV_AUTOPILOT {autopilot}) is neither PX4 (12) "
                                         "nor ArduPilot (3): give --autopilot px4|ardupilot to fly it anyway")
            else:
                log.info("autopilot: %s (HEARTBEAT.autopilot %d)", found.name, autopilot)
        elif found is not None and found is not self.dialect:
            self.dialect_mismatch = (f"--autopilot {self.dialect.name} was given, but the vehicle's HEARTBEAT says "
                                     f"{found.name} (MAV_AUTOPILOT {autopilot})")

    # -- waiting -------------------------------------------------------------------------
    def wait_for(self, predicate, timeout: float, what: str | Callable[[], str]) -> None:
        """Poll predicate until true; LinkError naming `what` (or what `what()` says is still
        missing then) after timeout seconds."""
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > end:
                raise LinkError(f"timed out after {timeout:.0f} s waiting for {what() if callable(what) else what}")
            time.sleep(0.02)

    def wait_heartbeat(self, timeout: float = 10.0) -> None:
        """The vehicle's first HEARTBEAT; WrongAutopilot when it is not the family asked for."""
        self.wait_for(lambda: self.telemetry.heartbeat_time > 0, timeout, "a vehicle heartbeat")
        if self.dialect_mismatch is not None:
            raise WrongAutopilot(self.dialect_mismatch)

    def require_dialect(self) -> Dialect:
        if self.dialect is None:
            raise LinkError("the autopilot's family is not known yet (no HEARTBEAT from it)")
        return self.dialect

    @property
    def target(self) -> tuple[int, int]:
        """(system, component) of the autopilot: the source of its first HEARTBEAT (another
        component on the same link, a camera, never takes its place)."""
        if self._autopilot_id is not None:
            return self._autopilot_id
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
        sent_at = time.monotonic()

        def send(confirmation: int) -> None:
            if confirmation:
                self.stats.command_retries += 1
            with self._send_lock:
                self.conn.mav.command_long_send(*self.target, cmd, confirmation, *p)

        result, tries = resend_until_acked(send, self._ack_cv, self._acks, cmd, timeout, retries, progress_timeout,
                                           self.silent_for)
        if result is None:
            raise LinkError(f"no COMMAND_ACK for command {cmd} after {tries} tries{self.silence_note()}")
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise CommandRejected(cmd, result, self._reason_since(sent_at))
        return result

    def silent_for(self) -> float:
        """Wall seconds since the last message of any kind came in on this link."""
        return time.monotonic() - self._last_received

    def silence_note(self) -> str:
        quiet = self.silent_for()
        return f" (nothing heard on the link for {quiet:.0f} s)" if quiet > SILENT_GIVE_UP_S else ""

    def send_command_long(self, target: tuple[int, int], cmd: int, confirmation: int, *params: float) -> None:
        """One COMMAND_LONG to (system, component), not waited on: for another component of the
        vehicle (a camera), whose sender waits for that component's own ACK."""
        p = list(params) + [0.0] * (7 - len(params))
        with self._send_lock:
            self.conn.mav.command_long_send(*target, cmd, confirmation, *p)

    def arm(self, force: bool = False, retry_s: float = 0.0) -> None:
        """Arm; a TEMPORARILY_REJECTED (PX4 while a pre-arm check is still settling) is asked
        again every half second for up to retry_s."""
        end = time.monotonic() + retry_s
        while True:
            try:
                self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196 if force else 0)
                return
            except CommandRejected as e:
                if e.result != mavlink.MAV_RESULT_TEMPORARILY_REJECTED or time.monotonic() > end:
                    raise
                time.sleep(0.5)

    def disarm(self, force: bool = False) -> None:
        self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196 if force else 0)

    def _reason_since(self, t0: float, settle_s: float = 0.3) -> str:
        """The warnings the vehicle sent since t0 (ArduPilot explains a refusal in STATUSTEXT
        "PreArm: ...", sometimes just after its ACK): waited for briefly, joined."""
        def texts() -> list[str]:
            return [txt for t, sev, txt in list(self.telemetry.statustext_log)
                    if t >= t0 - 0.05 and sev <= mavlink.MAV_SEVERITY_WARNING]

        end = time.monotonic() + settle_s
        while not texts() and time.monotonic() < end:
            time.sleep(0.02)
        return "; ".join(dict.fromkeys(texts()))

    def set_mode(self, name: str, retries: int = 10) -> None:
        """A mode by its family's name (PX4 'AUTO.LOITER', ArduPilot 'GUIDED')."""
        self.command(mavlink.MAV_CMD_DO_SET_MODE, *self.require_dialect().set_mode_params(name), retries=retries)

    def takeoff(self, altitude_m: float) -> None:
        """MAV_CMD_NAV_TAKEOFF to altitude_m as the dialect counts it (PX4 AMSL, ArduPilot
        above home: Dialect.takeoff_altitude)."""
        nan = float("nan")
        self.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, altitude_m)

    # -- parameters ----------------------------------------------------------------------
    def get_param(self, name: str, timeout: float = 1.0, retries: int = 5) -> float | None:
        """A parameter's value (PARAM_REQUEST_READ, resent until PARAM_VALUE answers); None
        when the vehicle has no such parameter (it stays silent, as PX4 and ArduPilot do)."""
        return self._param_exchange(name, None, timeout, retries)

    def set_param(self, name: str, value: float, timeout: float = 1.0, retries: int = 5) -> float:
        """PARAM_SET, resent until the vehicle echoes PARAM_VALUE; returns the value it now
        holds (a refusal leaves the old one: the caller compares)."""
        got = self._param_exchange(name, value, timeout, retries)
        if got is None:
            raise LinkError(f"no PARAM_VALUE for {name} after {retries} PARAM_SETs")
        return got

    def _param_exchange(self, name: str, value: float | None, timeout: float, retries: int) -> float | None:
        dialect = self.require_dialect()
        ptype = self._params.get(name, (0.0, mavlink.MAV_PARAM_TYPE_REAL32))[1]
        if value is not None and name not in self._params:  # the type first: PX4 packs integers bytewise
            if self._param_exchange(name, None, timeout, retries) is None:
                raise LinkError(f"the vehicle has no parameter {name}")
            ptype = self._params[name][1]
        for _ in range(retries):
            with self._param_cv:
                self._params.pop(name, None)
            with self._send_lock:
                if value is None:
                    self.conn.mav.param_request_read_send(*self.target, name.encode(), -1)
                else:
                    self.conn.mav.param_set_send(*self.target, name.encode(), dialect.param_encode(value, ptype), ptype)
            with self._param_cv:
                if self._param_cv.wait_for(lambda: name in self._params, timeout):
                    raw, ptype = self._params[name]
                    return dialect.param_value(raw, ptype)
        return None

    # -- streams -------------------------------------------------------------------------
    def request_streams(self) -> list[str]:
        """Ask for the telemetry the dialect needs (ArduPilot streams nothing unasked); each
        refusal is returned as a line, not raised: a message the vehicle cannot send at that
        rate is the operator's to read about, the readiness checks say what is missing."""
        refused = []
        for s in self.require_dialect().streams:
            try:
                self.set_message_interval(s.msg_id, s.hz)
            except (CommandRejected, LinkError) as e:
                refused.append(f"SET_MESSAGE_INTERVAL {mavlink.mavlink_map[s.msg_id].msgname}: {e}")
        return refused

    def land(self, retries: int = 10) -> None:
        self.command(mavlink.MAV_CMD_NAV_LAND, retries=retries)

    def return_to_launch(self, retries: int = 10) -> None:
        self.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, retries=retries)

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
