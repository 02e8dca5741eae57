"""PX4 SITL as the vehicle spoke it before dialects: the default, unchanged. Its commands are
commands.py, its flying flying.py, its failsafes failsafe.py, its setpoints incoming.py, its
telemetry telemetry.py; this module routes the dialect's calls to them."""

from __future__ import annotations

from collections.abc import Callable

from pymavlink.dialects.v20 import common as mavlink

from .. import commands
from ..commands import ATTITUDE_MODES, Command
from ..host import Host
from ..modes import px4_mode_name
from ..params import ParamStore
from ..telemetry import BUILDERS, DEFAULT_RATES
from . import Dialect

M = mavlink


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
        v._fly()
