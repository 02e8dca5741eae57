"""PX4 SITL as the vehicle spoke it before dialects: the default, unchanged. Its commands are
commands.py, its flying flying.py, its failsafes failsafe.py, its setpoints incoming.py, its
telemetry telemetry.py; this module routes the dialect's calls to them.

Its polygon fence (fence_protocol.Px4FenceProtocol, polyfence.py) is enforced as PX4's
navigator and commander do (Navigator::geofence_breach_check, Failsafe::fromGfActParam):
checked every 200 ms on the position estimate, a new breach in the air does GF_ACTION (0 none,
1 warning, 2 Hold, 3 Return, 4 Terminate, 5 Land; default 2); PX4 no longer predicts ahead of
the vehicle (GF_PREDICT is gone), so Hold stops it where the breach was seen, just outside.
Setpoints are not refused by the polygon (PX4 checks only repositions against it).
"""

from __future__ import annotations

from collections.abc import Callable

from pymavlink.dialects.v20 import common as mavlink

from .. import commands
from ..commands import ATTITUDE_MODES, Command
from ..fence_protocol import Px4FenceProtocol
from ..host import Host
from ..modes import px4_mode_name
from ..params import ParamStore
from ..polyfence import px4_allows
from ..telemetry import BUILDERS, DEFAULT_RATES
from . import Dialect

M = mavlink
GEOFENCE_CHECK_S = 0.2  # Navigator::geofence_breach_check's GEOFENCE_CHECK_INTERVAL_US
#: GF_ACTION -> the mode the failsafe enters (None: no mode change)
GF_MODES = {2: "AUTO.LOITER", 3: "AUTO.RTL", 5: "AUTO.LAND"}
GF_NAMES = {0: "None", 1: "Warning", 2: "Hold", 3: "Return", 4: "Terminate", 5: "Land"}


class PX4(Dialect):
    name = "px4"
    autopilot = M.MAV_AUTOPILOT_PX4
    initial_mode = "AUTO.LOITER"
    tracking_modes = frozenset({"OFFBOARD"})
    fleet_vectorised = True
    builders = BUILDERS

    def default_rates(self) -> dict[int, float]:
        return dict(DEFAULT_RATES)

    def param_store(self, signing: bool, armed: Callable[[], bool]) -> ParamStore:
        return ParamStore(signing=signing, armed=armed)

    def execute(self, v: Host, c: Command) -> tuple[int, Callable[[], object] | None]:
        return commands.execute(v, c)

    def on_set_mode(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """Obeyed like DO_SET_MODE, without an ACK."""
        name = px4_mode_name((msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF)
        if name is not None and name not in ATTITUDE_MODES and name != "OFFBOARD" and (
                name != "POSCTL" or v.manual_fresh()):
            v.set_mode(name)

    def on_setpoint(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        v._on_setpoint(msg)  # incoming.py: PX4's offboard setpoints

    def heard_heartbeat(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        v.heard_heartbeat(msg)  # failsafe.py: PX4's data-link loss

    def set_mode(self, v: Host, mode: str) -> None:
        if mode != v.mode:
            v.mode = mode
            v._rtl_phase = 0
            if mode in ("AUTO.LOITER", "POSCTL"):
                v._hold_here()
            if mode == "OFFBOARD" and v._last_setpoint is not None:
                v._fly_setpoint(v._last_setpoint)
        if mode == "AUTO.LAND":
            v.model.land()

    def step(self, v: Host) -> None:
        v._check_failsafes()
        if v.fences.zones:
            self.check_fence(v)
        v._fly()

    def fence_protocol(self, v, clock) -> Px4FenceProtocol:
        return Px4FenceProtocol(v, clock)

    def check_fence(self, v: Host) -> None:
        """Navigator::geofence_breach_check on the polygon and circle zones (the cylinder round
        home stays flying.py's), then the commander's failsafe on a new breach (edge-triggered:
        cleared by a mode change, as ClearCondition::OnModeChangeOrDisarm)."""
        f = v.fences
        if v.t + 1e-9 < f.next_check_t or v.fix is None:
            return
        f.next_check_t = v.t + GEOFENCE_CHECK_S
        action = int(v.params["GF_ACTION"])
        lat, lon, _ = v.home.ned_to_geodetic(v.estimate())
        breached = action != 0 and not px4_allows(f.zones, lat, lon)  # GF_ACTION_NONE: no breach flag
        was, f.breached = f.breached, breached
        s = v.model.state
        if not breached or was or not s.armed or s.landed:
            return
        v.statustext("Geofence: approaching or outside geofence", M.MAV_SEVERITY_CRITICAL)
        if action == 1:
            return  # Warning
        what = f"geofence breach, GF_ACTION {action} ({GF_NAMES.get(action, action)})"
        if action == 4:  # Terminate: the motors stop
            v.failsafe_log.append((v.t, what))
            v.statustext("Failsafe activated: flight termination", M.MAV_SEVERITY_EMERGENCY)
            v.model.disarm(force=True)
            return
        v._failsafe(what, GF_MODES.get(action, "AUTO.LOITER"))
