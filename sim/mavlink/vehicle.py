"""The simulated vehicle's MAVLink side, in the manner of PX4 SITL or of ArduCopter SITL.

It owns the links and the vehicle's state; where the autopilot families differ (modes,
commands, setpoints, failsafes, streams) it asks its dialect (dialects/: px4.py, the default,
and ardupilot.py). Its concerns live in mixins: what arrives is
dispatched in incoming.py (commands.py, mission.py, params.py), the PX4-style modes are flown
in flying.py through any FlightModel and inside the geofence (geofence.py), and telemetry and
STATUSTEXT go out in streams.py. The flying runs in `tick`, on simulated time; timers that wait
on a remote client (offboard setpoint loss, mission re-requests) run on wall-clock time,
because the client does.

Other components of the same system may share the vehicle's links, as behind a MAVLink router
(`components`: the camera, camera_component.py): what arrives goes to them first, and what one
of them takes the autopilot does not answer; they tick after the vehicle.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsFix, GpsModel
from sim.vehicle.model import FlightModel

from . import wire
from .battery import Battery
from .dialects import Dialect
from .dialects.px4 import PX4
from .failsafe import Failsafes
from .fence_protocol import FenceStore
from .flying import Flying
from .geofence import Geofence
from .incoming import Incoming
from .mission import MissionItem, MissionProtocol, MissionStore
from .quiet import QuietVehicle
from .signing import SigningGuard
from .streams import STATUSTEXT_KEEP, Streams, keep
from .udp import UdpLink

M = mavlink
log = logging.getLogger(__name__)


@dataclass
class VehicleCounters:
    commands: int = 0
    denied: int = 0
    fence_rejections: int = 0
    frames_sent: int = 0
    handler_errors: list[str] = field(default_factory=list)  # messages that raised in a handler
    statustext: list[str] = field(default_factory=list)


class Component(Protocol):
    """Another component of the vehicle's system on its links (camera_component.CameraComponent)."""

    def handle(self, msg: mavlink.MAVLink_message) -> bool: ...
    def tick(self, t: float | None = None) -> None: ...
    def quiet_until(self) -> float | None: ...


class MavlinkVehicle(Failsafes, Flying, Streams, Incoming, QuietVehicle):
    def __init__(
        self,
        model: FlightModel,
        links: list[UdpLink],
        home: HomePosition,
        gps: GpsModel,
        system_id: int = 1,
        signing: bool = False,
        clock: Callable[[], float] = time.monotonic,
        dialect: Dialect | None = None,
    ) -> None:
        """dialect: the autopilot family it speaks as (None: PX4)."""
        self.model, self.links, self.home, self.gps = model, links, home, gps
        #: the system's other components behind the same links (as behind a MAVLink router)
        self.components: list[Component] = []
        self.dialect = PX4() if dialect is None else dialect
        self.builders = self.dialect.builders  # telemetry builders by message id (streams.py)
        self.sysid = system_id
        self.clock = clock  # wall clock, for timers that wait on a client
        self._next_wall: dict[int, float] = {}
        self.params = self.dialect.param_store(signing, lambda: self.model.state.armed)
        self.mission = MissionStore()
        self.missions = MissionProtocol(self, self.mission, clock)
        self.fences = FenceStore()  # polygon and circle fences (MAV_MISSION_TYPE_FENCE)
        self.missions.fences = self.dialect.fence_protocol(self, clock)
        self.mode = self.dialect.initial_mode
        self.rates = self.dialect.default_rates()
        self._next_due = {k: 0.0 for k in self.rates}
        self._stream_next = 0.0  # simulated time the next stream message is due (streams.py)
        #: send each tick's telemetry as one datagram per link (SitlFleet sets it: a sendto costs
        #: 5-9 us of CPU here, and a fleet of 100 sent 9,100 a simulated second); a lone vehicle
        #: sends one packet per datagram, as PX4 does
        self.batch_streams = False
        #: a fleet's list of (vehicle, due stream ids): set, the vehicle hands its due telemetry to
        #: the fleet, which builds it for all vehicles at once (fleet_telemetry.py) and sends it
        self.stream_sink: list | None = None
        self.t = 0.0
        self.fix: GpsFix | None = None
        self.counters = VehicleCounters()
        self._target: np.ndarray | None = None  # NED hold/goto target (estimate frame)
        self._offboard_wall_t = -1e9  # when the last offboard setpoint arrived
        self._offboard_sim_t = -1e9  # the same in simulated time
        #: the latest setpoint heard outside OFFBOARD, flown on entering it (incoming.py)
        self._last_setpoint: mavlink.MAVLink_message | None = None
        self._manual_wall_t = -1e9  # when the last MANUAL_CONTROL arrived
        self._sticks = np.zeros(4)  # forward, right, up, yaw rate: each in [-1, 1]
        self._velocity_control = False  # the model tracks a velocity, not a position
        self._fence_hold = False  # holding inside after a breach
        self._rtl_phase = 0
        self._wp_reached = -1
        self.lockstep = False  # hold time at a companion's decision points (SitlConfig)
        self.hold_for_companion = False
        self.hold_wall_t = 0.0
        self._statustext_id = 0
        self.battery = Battery()
        key = links[0].mav.signing.secret_key if links else None
        self.signing_guard = SigningGuard(key) if key is not None else None
        for link in links if self.signing_guard is not None else []:
            self.signing_guard.install(link.mav)  # one replay table for every link
        self._init_failsafes()
        #: what the telemetry is built with: wire.ENCODER (payloads without message objects,
        #: the same bytes) unless a link signs, which needs pymavlink's messages
        self.enc = self.mav if self.signing_guard is not None or any(
            link.mav.signing.sign_outgoing for link in links) else wire.ENCODER

    # -- helpers -------------------------------------------------------------------------
    @property
    def mav(self) -> mavlink.MAVLink:
        return self.links[0].mav

    def fence(self) -> Geofence:
        return Geofence(self.params["GF_MAX_HOR_DIST"], self.params["GF_MAX_VER_DIST"])

    def send(self, msg: mavlink.MAVLink_message | wire.Packed) -> None:
        if "mavlink_signal" in self.failures:
            return  # injected link failure: nothing goes out
        links = self.links
        if type(msg) is wire.Packed:  # telemetry (self.enc): framed once for every link
            framed = None
            for link in links:
                framed = link.send_packed(msg, framed)
            return
        if len(links) > 1:  # the payload once for every link (each frames it with its own sequence)
            body = wire.payload(msg)
            for link in links:
                link.send(msg, body)
        else:
            for link in links:
                link.send(msg)

    def estimate(self) -> np.ndarray:
        """The autopilot's position estimate: truth plus the error it cannot see (what an EKF
        fed by this GPS and a barometer converges to: GpsModel.estimate_error). Targets are flown
        in this frame, as on a real drone."""
        return self.model.state.position_ned + self.gps.estimate_error

    def set_mode(self, mode: str) -> None:
        """Enter a mode as the dialect enters it (no checks: the caller made them)."""
        self.dialect.set_mode(self, mode)

    def arm(self) -> bool:
        ok = self.model.arm()
        if ok and self.model.state.landed:
            self._target = self.estimate()
        return ok

    def offboard_fresh(self) -> bool:
        """Lost only when the setpoints are stale in wall-clock time (the client's) and in
        simulated time too: a simulation stalled by a loaded machine has not lost its client."""
        limit = self.params["COM_OF_LOSS_T"]
        return self.clock() - self._offboard_wall_t <= limit or self.t - self._offboard_sim_t <= limit

    def manual_fresh(self) -> bool:
        return self.clock() - self._manual_wall_t <= self.params["COM_RC_LOSS_T"]

    def set_rate(self, msg_id: int, hz: float) -> None:
        self.rates[msg_id] = hz
        self._next_due[msg_id] = self.t
        self._stream_next = min(self._stream_next, self.t)

    # -- the tick ------------------------------------------------------------------------
    def service(self) -> None:
        """Answer whatever has arrived, without advancing time (between physics ticks)."""
        for link in self.links:
            for msg in link.poll():
                if "mavlink_signal" in self.failures and not _restores_signal(msg):
                    continue  # injected link failure: nothing is heard but the command that ends it
                try:
                    if not self._to_components(msg):
                        self.handle(msg)
                except Exception as e:  # a well-formed message with absurd content: drop it, fly on
                    keep(self.counters.handler_errors, f"{msg.get_type()}: {type(e).__name__}: {e}", STATUSTEXT_KEEP)
                    log.exception("dropped %s after a handler error", msg.get_type())

    def _to_components(self, msg: mavlink.MAVLink_message) -> bool:
        """Hand a message to the system's other components; True when one took it (it was
        addressed to it, or is a broadcast only it answers): the autopilot leaves it alone."""
        taken = False
        for c in self.components:
            taken = c.handle(msg) or taken
        return taken

    def hold(self) -> None:
        """Companion lockstep (SitlConfig.companion_lockstep): hold simulated time here, at a
        decision point (a capture asked for ahead has gone out), until the companion's next
        command to any component of this system."""
        if self.lockstep:
            self.hold_for_companion, self.hold_wall_t = True, self.clock()

    def release(self) -> None:
        """The companion acts (a command to any component): time runs on."""
        self.hold_for_companion = False

    def tick(self, t: float, serve: bool = True, sampled: bool = False) -> None:
        """One simulated step at time t: answer what arrived (unless the caller just did, as a
        fleet does for the vehicles whose sockets are ready), fly, stream. sampled: the caller
        has just taken this tick's GPS fix (sample_gps; a fleet's quiet ticks do)."""
        dt, self.t = max(t - self.t, 0.0), t
        if serve:
            self.service()
        s = self.model.state
        if not sampled:
            self.sample_gps(t)
        self.battery.step(dt, s.armed, s.armed and not s.landed, self.params["UAVS_BAT_ENDUR_S"],
                          self.params["SIM_BAT_MIN_PCT"] / 100.0)
        s.battery_remaining, s.battery_voltage = self.battery.reading, self.battery.voltage
        self.dialect.step(self)  # failsafes, then the mode's flying
        self._stream()
        for c in self.components:  # after this tick's telemetry: a frame of t follows its samples
            c.tick(t)
        self.missions.poll()

    def sample_gps(self, t: float) -> None:
        """The receiver's fix at t, when one is due; the position controller follows it."""
        s = self.model.state
        fix = self.gps.sample(t, s.position_ned, s.velocity_ned)
        if "gps" in self.failures:
            self.fix = None
        elif fix is not None:
            self.fix = fix
            self._follow_estimate()

    # -- the mission protocol's host -------------------------------------------------------
    def mission_item_allowed(self, item: MissionItem) -> bool:
        if self.fence().allows(self._item_ned(item)):
            return True
        self.counters.fence_rejections += 1
        self.statustext(f"Mission item {item.seq} outside the geofence", M.MAV_SEVERITY_WARNING)
        return False

    def mission_running(self) -> bool:
        return self.mode == "AUTO.MISSION" and self.model.state.armed

    def mission_changed(self, cleared: bool) -> None:
        if self.mode != "AUTO.MISSION":
            return
        if cleared:
            self.set_mode("AUTO.LOITER")
        else:
            self._target = None  # fly to the new current item

    def send_mission_current(self) -> None:
        self.send(self.mission_current())

    def mission_current(self) -> mavlink.MAVLink_message | wire.Packed:
        return self.enc.mission_current_encode(self.mission.current, len(self.mission.items), self._mission_state())

    def _mission_state(self) -> int:
        if not self.mission.items:
            return M.MISSION_STATE_NO_MISSION
        if self.mission.current >= len(self.mission.items):
            return M.MISSION_STATE_COMPLETE
        return M.MISSION_STATE_ACTIVE if self.mode == "AUTO.MISSION" else M.MISSION_STATE_NOT_STARTED


def _restores_signal(msg: mavlink.MAVLink_message) -> bool:
    return (msg.get_type() in ("COMMAND_LONG", "COMMAND_INT") and msg.command == M.MAV_CMD_INJECT_FAILURE
            and int(msg.param1) == M.FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL)
