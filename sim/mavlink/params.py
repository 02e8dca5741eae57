"""The parameter store and protocol (PARAM_REQUEST_LIST / _READ / PARAM_SET -> PARAM_VALUE).
A realistic handful of PX4's parameters with their ranges, all REAL32 on the wire; a dialect
may bring its own set (dialects/ardupilot.py: ArduCopter's names, units and wire types), with
aliases through which the shared flying code reads them under one internal name."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink


@dataclass
class Param:
    value: float
    lo: float
    hi: float
    doc: str
    readonly: bool = False  # reflects configuration the link must not change (e.g. signing)
    values: tuple[int, ...] | None = None  # an enum parameter: only these
    #: MAV_PARAM_TYPE on the wire (the value itself always travels as a float, C-cast, as
    #: ArduPilot and PX4's REAL32 parameters both send it)
    wire_type: int = mavlink.MAV_PARAM_TYPE_REAL32


def default_params() -> dict[str, Param]:
    return {
        "MIS_TAKEOFF_ALT": Param(3.5, 0.5, 100.0, "default takeoff altitude (m above home)"),
        "MPC_XY_CRUISE": Param(3.0, 0.5, 15.0, "cruise speed in missions (m/s)"),
        "MPC_XY_VEL_MAX": Param(5.0, 0.5, 15.0, "maximum horizontal speed (m/s)"),
        "MPC_Z_VEL_MAX_UP": Param(2.0, 0.5, 5.0, "maximum climb rate (m/s)"),
        "NAV_ACC_RAD": Param(0.4, 0.05, 10.0, "waypoint acceptance radius (m)"),
        "RTL_RETURN_ALT": Param(5.0, 1.0, 100.0, "return altitude above home (m)"),
        "RTL_LAND_DELAY": Param(0.0, -1.0, 300.0, "Return's delay before landing (s); -1: loiter over home, never "
                                "land (our vehicle lands after its return whatever it says)"),
        "GF_MAX_HOR_DIST": Param(100.0, 1.0, 10000.0, "geofence: max horizontal distance from home (m)"),
        "GF_MAX_VER_DIST": Param(30.0, 1.0, 1000.0, "geofence: max altitude above home (m)"),
        "GF_ACTION": Param(2.0, 0.0, 5.0, "polygon/circle fence breach action: 0 none, 1 warning, 2 Hold, 3 Return, "
                           "4 Terminate, 5 Land (the cylinder round home always holds inside)",
                           values=(0, 1, 2, 3, 4, 5)),
        "COM_OF_LOSS_T": Param(1.0, 0.1, 60.0, "offboard setpoint timeout (s)"),
        "COM_RC_LOSS_T": Param(0.5, 0.1, 35.0, "manual control (MANUAL_CONTROL) timeout in POSCTL (s)"),
        "COM_FAIL_ACT_T": Param(5.0, 0.0, 25.0, "hold this long (s) before a failsafe's action (offboard loss)"),
        "COM_OBL_RC_ACT": Param(0.0, 0.0, 5.0, "offboard loss action: 0 Position (no sticks: Return), 1 Altitude, "
                                "2 Manual (no sticks: Return), 3 Return, 4 Land, 5 Hold", values=(0, 1, 2, 3, 4, 5)),
        "COM_DL_LOSS_T": Param(10.0, 5.0, 300.0, "data link (heartbeat) loss timeout (s)"),
        "NAV_DLL_ACT": Param(2.0, 0.0, 3.0, "data link loss action: 0 off, 1 Hold, 2 Return, 3 Land (PX4 default 0)",
                             values=(0, 1, 2, 3)),
        "BAT_LOW_THR": Param(0.15, 0.12, 0.5, "battery low threshold (warning)"),
        "BAT_CRIT_THR": Param(0.07, 0.05, 0.25, "battery critical threshold (COM_LOW_BAT_ACT)"),
        "BAT_EMERGEN_THR": Param(0.05, 0.03, 0.1, "battery emergency threshold (land)"),
        "COM_LOW_BAT_ACT": Param(3.0, 0.0, 3.0, "battery failsafe: 0 warning, 2 Land, 3 Return at critical and land "
                                 "at emergency (PX4 default 0)", values=(0, 2, 3)),
        "SYS_FAILURE_EN": Param(0.0, 0.0, 1.0, "1: MAV_CMD_INJECT_FAILURE accepted", values=(0, 1)),
        "UAVS_BAT_ENDUR_S": Param(1500.0, 10.0, 36000.0, "battery endurance in hover from full (s)"),
        "SIM_BAT_MIN_PCT": Param(50.0, 0.0, 100.0, "the simulated battery drains no lower than this (%), as PX4 "
                                 "SITL: long simulations never run out; 0 to test the battery failsafes"),
        "SYS_AUTOSTART": Param(4001.0, 0.0, 1e6, "airframe: generic quadrotor x"),
        "UAVS_CAM_RATE": Param(0.0, 0.0, 30.0, "camera frames streamed per second (0: on request)"),
        "UAVS_SIGNING": Param(0.0, 0.0, 1.0, "1: MAVLink2 signing required (read-only, set at start)", True),
    }


#: fence and failsafe parameters: refused while armed (a link must not widen the fence or switch
#: a failsafe off in flight)
LOCKED_WHEN_ARMED = ("GF_", "COM_", "NAV_DLL_", "BAT_", "SYS_FAILURE_EN", "RTL_RETURN_ALT", "RTL_LAND_DELAY")


#: an internal name the shared code reads -> (the dialect's parameter, factor): internal value =
#: parameter value * factor (ArduCopter's WPNAV_SPEED in cm/s read as MPC_XY_CRUISE in m/s)
Aliases = dict[str, tuple[str, float]]


class ParamStore:
    def __init__(self, signing: bool = False, armed: Callable[[], bool] = lambda: False,
                 params: dict[str, Param] | None = None, locked: tuple[str, ...] | None = None,
                 aliases: Aliases | None = None, hidden: dict[str, float] | None = None) -> None:
        """params: the dialect's parameters (None: PX4's); locked: name prefixes refused while
        armed (None: LOCKED_WHEN_ARMED); aliases: internal names read through a parameter;
        hidden: internal values the shared code reads that the dialect has no parameter for
        (never listed, never set over the link)."""
        self.armed = armed
        self.params = default_params() if params is None else params
        self.locked = LOCKED_WHEN_ARMED if locked is None else locked
        self.aliases = dict(aliases or {})
        self.params["UAVS_SIGNING"].value = float(signing)
        self.names = list(self.params)
        #: name -> value: what every vehicle reads several times a tick (one dict lookup);
        #: set() is the only way a value changes, and it updates both
        self.values = {name: p.value for name, p in self.params.items()}
        self.values.update(hidden or {})
        self._refresh_aliases()

    def _refresh_aliases(self) -> None:
        for internal, (name, factor) in self.aliases.items():
            self.values[internal] = self.params[name].value * factor

    def __getitem__(self, name: str) -> float:
        return self.values[name]

    def set(self, name: str, value: float, remote: bool = False) -> tuple[bool, str]:
        """remote: a PARAM_SET from the link, which sets the dialect's own names only."""
        if name in self.aliases and not remote:  # the shared code's name for one of the dialect's parameters
            name, factor = self.aliases[name]
            value = value / factor
        p = self.params.get(name)
        if p is None:
            return False, f"unknown parameter {name}"
        if p.readonly:
            return False, f"{name} is read-only"
        if not math.isfinite(value) or not p.lo <= value <= p.hi:
            return False, f"{name}={value} outside [{p.lo}, {p.hi}]"
        if p.values is not None and value not in p.values:
            return False, f"{name}={value} is not one of {list(p.values)}"
        if self.locked and name.startswith(self.locked) and self.armed() and value != p.value:
            return False, f"{name} cannot change while armed"
        p.value = self.values[name] = float(value)
        if self.aliases:
            self._refresh_aliases()
        return True, ""

    def index(self, name: str) -> int:
        return self.names.index(name)


def _param_id(msg: mavlink.MAVLink_message) -> str:
    raw = msg.param_id
    text = raw if isinstance(raw, str) else bytes(raw).decode("ascii", errors="replace")
    return text.rstrip("\0")


def param_value(mav: mavlink.MAVLink, store: ParamStore, name: str) -> mavlink.MAVLink_message:
    return mav.param_value_encode(name.encode(), store[name], store.params[name].wire_type, len(store.names),
                                  store.index(name))


def param_replies(mav: mavlink.MAVLink, store: ParamStore,
                  msg: mavlink.MAVLink_message) -> tuple[list[mavlink.MAVLink_message], str | None]:
    """PARAM_REQUEST_LIST / PARAM_REQUEST_READ / PARAM_SET -> (PARAM_VALUEs to send, why a set
    was refused). A refused set echoes the value kept, as PX4 does; an unknown name gets no
    PARAM_VALUE (the client times out, as with PX4)."""
    kind = msg.get_type()
    if kind == "PARAM_REQUEST_LIST":
        return [param_value(mav, store, n) for n in store.names], None
    if kind == "PARAM_REQUEST_READ":
        name = _param_id(msg)
        if 0 <= msg.param_index < len(store.names):
            name = store.names[msg.param_index]
        return ([param_value(mav, store, name)] if name in store.params else []), None
    if kind == "PARAM_SET":
        name = _param_id(msg)
        ok, why = store.set(name, float(msg.param_value), remote=True)
        return ([param_value(mav, store, name)] if name in store.params else []), (None if ok else why)
    return [], None
