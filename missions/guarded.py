"""A search flight that always ends with the vehicle on the ground or told to get there.

`guarded_search` runs take-off (or a resumed search's rejoin), search and landing; whatever
stops it (Ctrl-C, SIGTERM, a link error, a timeout, an exception in the policy) it stops the
OFFBOARD stream, hands the vehicle to `--on-abort` (rtl, land or hold; see
autopilot_bridge.service.abort), waits bounded for the disarm, and returns the cause and the exit
status for the CLI. Signals raise in the main thread only while the flight runs; during the
bring-down a further signal only ends the wait (the vehicle keeps its RTL/LAND), it never
interrupts a command half-sent.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.abort import AbortAction, Touchdown, bring_down
from autopilot_bridge.service.policy_service import PolicyService, SearchLog

EXIT_OK = 0
EXIT_FAILED = 1  # the flight failed (link error, timeout, exception): the vehicle was brought down
EXIT_SHORT = 3  # the search ended (move cap) short of |R| targets
# interrupted by signal N: 128 + N, the shell's convention (SIGINT 130, SIGTERM 143)


class Interrupted(BaseException):
    """A signal asked the flight to stop (BaseException: no `except Exception` swallows it)."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


@dataclass
class SignalState:
    bringing_down: bool = False
    during_abort: int = 0
    #: the signal whose Interrupted was raised (None: none yet)
    pending: int | None = None

    def raise_pending(self) -> None:
        """Raise the signal's Interrupted again if it never reached the flight's handler: a raise
        that lands in a finaliser or a weakref callback is printed and dropped by Python ("Exception
        ignored in ..."), and then a SIGTERM at move 4 let the search fly on to its end and exit 0
        (seen once in CI's suite). Called at every decision, in the main thread."""
        if self.pending is not None and not self.bringing_down:
            raise Interrupted(self.pending)


@contextmanager
def signals_raise() -> Iterator[SignalState]:
    """SIGINT and SIGTERM raise `Interrupted` in the main thread until `bringing_down` is set;
    after that they are only counted. Elsewhere than the main thread: nothing is installed."""
    state = SignalState()
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(signum: int, _frame: object) -> None:
        if state.bringing_down:
            state.during_abort += 1  # mid-abort a signal only counts (and ends the abort's wait)
            return
        if state.pending is not None:
            return  # one raise only; if it was dropped, the next decision raises it (raise_pending)
        state.pending = signum
        raise Interrupted(signum)

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield state
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@dataclass(frozen=True)
class FlightEnd:
    log: SearchLog
    exit_code: int
    cause: str | None  # None: the search ran to its end and landed
    touchdown: Touchdown | None  # how the bring-down went, when there was one

    def to_dict(self) -> dict:
        return {"exit_code": self.exit_code, "cause": self.cause,
                "touchdown": None if self.touchdown is None else self.touchdown.to_dict()}


def guarded_search(service: PolicyService, link: VehicleLink, on_abort: AbortAction | str = AbortAction.rtl,
                   abort_timeout_s: float = 120.0, hold_s: float = 60.0,
                   echo: Callable[[str], None] = print, move_timeout_s: float = 20.0,
                   rejoin: Callable[[], tuple[int, np.ndarray, float]] | None = None) -> FlightEnd:
    """rejoin: a journaled search resumed (`uavsearch run --resume`): instead of the take-off,
    it takes the vehicle back wherever it is (autopilot_bridge.service.resume) and returns the decision
    loop's (move, cell, t_k) to go on from; a failure there brings the vehicle down as any."""
    with signals_raise() as sig:
        shown = service.on_progress

        def each_decision(p) -> None:
            sig.raise_pending()
            if shown is not None:
                shown(p)

        service.on_progress = each_decision
        try:
            if rejoin is None:
                service.take_off()
                service.run(timeout_per_move=move_timeout_s)
            else:
                service.run(timeout_per_move=move_timeout_s, resume=rejoin())
            service.land()
            found, need = len(service.log.believed_found), service.spec.grid.n_targets
            if found < need:
                return FlightEnd(service.log, EXIT_SHORT,
                                 f"the search ended after {len(service.log.cells) - 1} moves with {found} of "
                                 f"{need} targets found", None)
            return FlightEnd(service.log, EXIT_OK, None, None)
        except Interrupted as e:
            cause, code = f"interrupted by {e}", 128 + e.signum
        except KeyboardInterrupt:
            cause, code = "interrupted by SIGINT", 128 + signal.SIGINT
        except Exception as e:  # noqa: BLE001 - every failure brings the vehicle down
            cause, code = f"{type(e).__name__}: {e}", EXIT_FAILED
        sig.bringing_down = True
        echo(f"search stopped: {cause}")
        service.stop_setpoints()
        td = bring_down(link, on_abort, abort_timeout_s, hold_s, echo, stop_waiting=lambda: sig.during_abort > 0)
        state = "landed and disarmed" if td.disarmed else "STILL ARMED"
        echo(f"vehicle {state} after {td.waited_s:.0f} s" + (f" ({td.note})" if td.note else ""))
        return FlightEnd(service.log, code, cause, td)
