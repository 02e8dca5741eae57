"""The vehicle as the command handlers and the dialects see it: one object holding the state
(airframe, parameters, mission, fix, mode, targets) and the few actions they may take.

A Protocol, not the class: commands.py and dialects/ type against it instead of importing
vehicle.py, which imports them (through incoming.py and flying.py) - the import circle
commands -> vehicle -> incoming/flying -> commands is gone, and a handler can be read, and
tested, against exactly what it may touch. MavlinkVehicle satisfies it (vehicle.py)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsFix, GpsModel
from sim.vehicle.model import FlightModel

if TYPE_CHECKING:  # type names only: neither module imports this one
    from .fence_protocol import FenceStore
    from .mission import MissionStore
    from .params import ParamStore


class Host(Protocol):
    """What a command handler or a dialect may read and do."""

    model: FlightModel
    home: HomePosition
    gps: GpsModel
    params: ParamStore
    mission: MissionStore
    fences: FenceStore  # the polygon/circle fence uploaded (fence_protocol.py)
    camera: Callable[[np.ndarray, float], np.ndarray] | None
    fix: GpsFix | None
    mode: str
    t: float  # simulated seconds since boot
    sysid: int
    rates: dict[int, float]
    builders: dict[int, Any]  # telemetry builders by message id (the dialect's)
    dialect: Any  # the vehicle's Dialect (dialects/__init__.py)
    clock: Callable[[], float]  # wall clock, for timers that wait on a client
    _target: np.ndarray | None
    _velocity_control: bool
    failsafe_log: list[tuple[float, str]]
    # PX4's own (dialects/px4.py routes to them): return phase, the setpoint heard outside OFFBOARD
    _rtl_phase: int
    _last_setpoint: mavlink.MAVLink_message | None

    @property
    def mav(self) -> mavlink.MAVLink: ...

    def send(self, msg: Any) -> None: ...

    def fence(self) -> Any: ...

    def statustext(self, text: str, severity: int = ...) -> None: ...

    def estimate(self) -> np.ndarray: ...

    def set_mode(self, mode: str) -> None: ...

    def arm(self) -> bool: ...

    def takeoff(self, alt_amsl: float) -> int: ...

    def goto(self, ned: np.ndarray, speed: float | None = None) -> bool: ...

    def retarget(self, speed: float) -> None: ...

    def offboard_fresh(self) -> bool: ...

    def manual_fresh(self) -> bool: ...

    def set_rate(self, msg_id: int, hz: float) -> None: ...

    def send_message(self, msg_id: int, snap: Any = None) -> bool: ...

    def capture_at(self, time_s: float) -> None: ...

    def inject_failure(self, unit: int, kind: int) -> Any: ...

    def _command_model(self, target_est: np.ndarray, yaw: float | None = None, speed: float | None = None) -> None: ...

    def _hold_here(self) -> None: ...

    # PX4's setpoints, failsafes and flying (incoming.py, failsafe.py, flying.py)
    def _on_setpoint(self, msg: mavlink.MAVLink_message) -> None: ...

    def _fly_setpoint(self, msg: mavlink.MAVLink_message) -> None: ...

    def heard_heartbeat(self, msg: mavlink.MAVLink_message) -> None: ...

    def _check_failsafes(self) -> None: ...

    def _failsafe(self, what: str, mode: str, severity: int = ...) -> None: ...

    def _fly(self) -> None: ...
