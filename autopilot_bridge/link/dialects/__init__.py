"""Autopilot dialects: one object per family (PX4, ArduPilot), chosen from the vehicle's
HEARTBEAT.autopilot or by name (`uavsearch run --autopilot`)."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .ardupilot import ArduPilot
from .base import Dialect, FailsafeRule, FenceParam, Stream
from .px4 import PX4

__all__ = ["ArduPilot", "Dialect", "FailsafeRule", "FenceParam", "PX4", "Stream", "by_name", "for_autopilot", "NAMES"]

_BY_NAME: dict[str, Dialect] = {"px4": PX4(), "ardupilot": ArduPilot()}
NAMES = ("auto", *_BY_NAME)


def by_name(name: str) -> Dialect:
    """'px4' or 'ardupilot' -> its dialect; anything else is a ValueError naming it."""
    try:
        return _BY_NAME[name.lower()]
    except KeyError:
        raise ValueError(f"unknown autopilot {name!r}: expected one of {', '.join(_BY_NAME)} (or auto)") from None


def for_autopilot(autopilot: int) -> Dialect | None:
    """HEARTBEAT.autopilot -> its dialect; None for a family the companion does not speak."""
    if autopilot == mavlink.MAV_AUTOPILOT_PX4:
        return _BY_NAME["px4"]
    if autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA:
        return _BY_NAME["ardupilot"]
    return None
