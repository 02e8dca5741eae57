"""Bringing the vehicle down when a search cannot go on (interrupted, link error, timeout, a
bug in the policy): the one rule is that the companion never walks away from an armed vehicle
in the air without having told it to come down, and says what it saw.

`rtl` and `land` hand the vehicle to the autopilot's own RTL / LAND; `hold` hands it to the
operator (the dialect's hold mode: PX4's AUTO.LOITER, ArduCopter's BRAKE, which holds without
sticks where its LOITER would follow a throttle stick at rest) for a bounded time and lands it
if nobody has by then. Each
waits, bounded, for the disarm that follows the touchdown. A refused or unanswered command
falls back to LAND; if even that gets no answer the outcome says so (the autopilot's own
offboard-loss failsafe is then all that is left).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from enum import StrEnum

from ..link.connection import CommandRejected, LinkError, VehicleLink

ON_GROUND = 1  # MAV_LANDED_STATE_ON_GROUND


class AbortAction(StrEnum):
    rtl = "rtl"
    land = "land"
    hold = "hold"


@dataclass(frozen=True)
class Touchdown:
    """How the bring-down went; `disarmed` is the one that matters."""

    action: str
    commanded: list[str]
    disarmed: bool
    waited_s: float
    note: str = ""

    def to_dict(self) -> dict:
        return asdict(self)


def _try(cmd: Callable[[], None], name: str, commanded: list[str], notes: list[str]) -> bool:
    try:
        cmd()
    except (CommandRejected, LinkError, OSError) as e:
        notes.append(f"{name} failed: {e}")
        return False
    commanded.append(name)
    return True


def bring_down(link: VehicleLink, action: AbortAction | str, timeout_s: float = 120.0,
               hold_s: float = 60.0, echo: Callable[[str], None] = print,
               stop_waiting: Callable[[], bool] = lambda: False, link_lost_s: float = 5.0) -> Touchdown:
    """Command `action`, then wait up to timeout_s (hold: hold_s for the operator, then land)
    for the vehicle to disarm. `stop_waiting()` true ends the wait early (a second Ctrl-C);
    the vehicle keeps the command it was given. With no heartbeat for link_lost_s there is
    nobody to wait for: the outcome says the vehicle's own failsafe is all that is left."""
    action = AbortAction(action)
    t0 = time.monotonic()
    commanded: list[str] = []
    notes: list[str] = []
    tel = link.telemetry
    if not tel.armed:  # a heartbeat newer than now settles it (an arm just ACKed may not show yet)
        end = t0 + 2.5
        while tel.heartbeat_time < t0 and time.monotonic() < end:
            time.sleep(0.05)
    if not tel.armed:
        return Touchdown(action.value, commanded, True, 0.0, "never armed or already disarmed")
    if tel.landed_state == ON_GROUND:  # armed on the ground (e.g. failed during take-off)
        _try(link.disarm, "disarm", commanded, notes)
    elif link.dialect is not None and link.dialect.descending(tel.mode):  # already coming down (Ctrl-C while landing)
        notes.append(f"already in {tel.mode}: kept it")
        echo(f"abort: the vehicle is already in {tel.mode}; waiting for disarm (up to {timeout_s:.0f} s)")
    else:
        # a link already silent (cut, out of range) gets a few tries, not the full ~22 s of
        # resends: the vehicle's own failsafe is acting, and the operator hears so sooner
        tries = 3 if time.monotonic() - tel.heartbeat_time > link_lost_s else 10
        ok = {
            AbortAction.rtl: lambda: _try(lambda: link.return_to_launch(tries), "RTL", commanded, notes),
            AbortAction.land: lambda: _try(lambda: link.land(tries), "LAND", commanded, notes),
            AbortAction.hold: lambda: _try(lambda: link.set_mode(link.require_dialect().hold_mode, tries), "HOLD",
                                           commanded, notes),
        }[action]()
        lost = time.monotonic() - tel.heartbeat_time > link_lost_s
        if not ok and action is not AbortAction.land and not lost:  # refused, or unanswered on a live link
            _try(link.land, "LAND", commanded, notes)
        echo(f"abort: {' then '.join(commanded) or 'no command was accepted'}; waiting for disarm "
             f"(up to {timeout_s:.0f} s)" + (f" [{'; '.join(notes)}]" if notes else ""))
    landing_forced = False
    deadline = timeout_s + (hold_s if action is AbortAction.hold else 0.0)
    while tel.armed:
        waited = time.monotonic() - t0
        if stop_waiting():
            notes.append("operator stopped waiting")
            break
        if time.monotonic() - tel.heartbeat_time > link_lost_s:
            break
        if action is AbortAction.hold and not landing_forced and waited > hold_s:
            echo(f"abort: nobody landed the vehicle within {hold_s:.0f} s of HOLD: landing it")
            landing_forced = _try(link.land, "LAND", commanded, notes) or True
        if waited > deadline:
            notes.append(f"still armed after {deadline:.0f} s")
            if tel.landed_state == ON_GROUND:  # down but not auto-disarmed: finish the job
                _try(link.disarm, "disarm", commanded, notes)
            break
        time.sleep(0.05)
    if tel.armed and time.monotonic() - tel.heartbeat_time > 3.0:
        notes.append("no heartbeat from the vehicle for "
                     f"{time.monotonic() - tel.heartbeat_time:.0f} s: its own failsafe is all that is left")
    return Touchdown(action.value, commanded, not tel.armed, round(time.monotonic() - t0, 2), "; ".join(notes))
