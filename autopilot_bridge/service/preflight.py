"""Before take-off: would a dead companion leave this vehicle in the air?

The companion flies the vehicle with a stream of position setpoints; when it dies (killed,
hung, its link cut) only the autopilot's own failsafe brings the vehicle down. PX4 leaves
OFFBOARD after COM_OF_LOSS_T and does COM_OBL_RC_ACT; ArduCopter's GUIDED holds the last
setpoint for ever unless its GCS failsafe (FS_GCS_ENABLE) watches this companion's heartbeat
(SYSID_MYGCS). The dialect lists those parameters and what is safe (`Dialect.failsafe_rules`);
here they are read off the vehicle and the flight is refused, naming each parameter and a safe
value, or with `set_safe` set to that value (each change logged).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from ..link.connection import LinkError, VehicleLink

log = logging.getLogger(__name__)


class UnsafeFailsafe(RuntimeError):
    """The vehicle's companion-loss failsafe would not bring it down: the companion will not fly it."""


@dataclass(frozen=True)
class FailsafeReading:
    name: str
    value: float | None  # None: the vehicle has no such parameter
    ok: bool
    safe: float
    why: str


def read_failsafe(link: VehicleLink, companion_sysid: int, timeout: float = 0.5,
                  retries: int = 8) -> list[FailsafeReading]:
    """Each failsafe parameter the dialect names, read off the vehicle and judged; a parameter
    the vehicle lacks is judged at the rule's default, or unsafe when the rule has none.
    Eight tries: over a radio losing 20 % each way one request and its answer are lost 36 % of
    the time, four tries all failing (1.7 %) refused flights a sound vehicle would have flown."""
    out = []
    for rule in link.require_dialect().failsafe_rules(companion_sysid):
        value = link.get_param(rule.name, timeout=timeout, retries=retries)
        judged = value if value is not None else rule.default
        out.append(FailsafeReading(rule.name, value, judged is not None and bool(rule.ok(judged)), rule.safe, rule.why))
    return out


def _fmt(v: float) -> str:
    return f"{v:g}"


def ensure_failsafe(link: VehicleLink, companion_sysid: int, set_safe: bool = False,
                    echo: Callable[[str], None] = log.info) -> list[str]:
    """Refuse (UnsafeFailsafe) a vehicle whose companion-loss failsafe would leave it flying,
    naming each parameter, its value and a safe one; with set_safe, write the safe values
    instead (PARAM_SET, read back) and return what was changed, one line each."""
    readings = read_failsafe(link, companion_sysid)
    bad = [r for r in readings if not r.ok]
    if not bad:
        return []
    if not set_safe:
        lines = [f"{r.name} = {'(absent)' if r.value is None else _fmt(r.value)}: {r.why}; a safe value: "
                 f"{_fmt(r.safe)}" for r in bad]
        fix = " ".join(f"{r.name}={_fmt(r.safe)}" for r in bad)
        raise UnsafeFailsafe(
            f"refusing to fly: a companion that dies would leave this {link.require_dialect().name} vehicle in the "
            "air. " + " | ".join(lines) + f". Set {fix} on the vehicle, or run with --set-failsafe")
    changed = []
    for r in bad:
        if r.value is None:
            raise UnsafeFailsafe(f"refusing to fly: the vehicle has no parameter {r.name} ({r.why}); "
                                 "--set-failsafe cannot set it")
        try:
            got = link.set_param(r.name, r.safe)
        except LinkError as e:
            raise UnsafeFailsafe(f"refusing to fly: setting {r.name} = {_fmt(r.safe)} failed: {e}") from e
        if abs(got - r.safe) > 1e-3 * max(1.0, abs(r.safe)):
            raise UnsafeFailsafe(f"refusing to fly: the vehicle kept {r.name} = {_fmt(got)} after PARAM_SET "
                                 f"{_fmt(r.safe)}")
        line = f"--set-failsafe: {r.name} {_fmt(r.value)} -> {_fmt(got)}"
        echo(line)
        changed.append(line)
    if link.require_dialect().heartbeat_feeds_failsafe:
        # ArduPilot's GCS failsafe is armed only once it has heard the system it now watches:
        # a companion dying before its next 1 Hz heartbeat would go unnoticed (measured on our
        # emulation: a take-off and a leg in under a second, then silence, hovered for ever)
        link.heartbeat_now()
    return changed
