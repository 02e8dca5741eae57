"""Rejoining the vehicle after the companion restarted, to go on with a journaled search.

While the companion was gone the vehicle did what its failsafes say (sim/mavlink/failsafe.py,
PX4's): with no setpoints for COM_OF_LOSS_T it holds, COM_FAIL_ACT_T later it returns and
lands, and with no companion heartbeat for COM_DL_LOSS_T it returns too. So the restarted
companion finds it in one of two states, and `rejoin` takes it from either to the same place:
in the air over the journal's cell, streaming setpoints in OFFBOARD, ready for the journal's
next decision.

- In the air (holding, returning, or still in OFFBOARD): the setpoint stream starts where it
  is, OFFBOARD is taken back, and the decision loop's first leg flies it to the journal's cell.
  No take-off.
- On the ground (landed by its failsafe, perhaps disarmed): armed and taken off again where it
  stands, then the same. The launch point is not registered again: after a return the vehicle
  stands where its GPS-fed estimate put home, off the true home by the GPS bias, and the
  journal's position posterior knows the bias better than "it is on its pad" would.

The clock: decisions run on the vehicle's simulated clock, which ran on while nobody decided.
The journal's times (the position filter's last fix, the found targets' sightings, the next
decision t_k) stay as they were, on that same clock: the filter predicts across the gap (its
covariance, and the bias's drift, grow with it, as they should: nobody watched), and the next
decision is re-anchored to the first point of the journal's decision lattice (t_k + n periods)
a period after the vehicle's clock now, so the first leg has its period to fly and settle (a
long leg back from home slips it, counted, as any leg that has not settled). A vehicle whose
clock is behind the journal's has restarted: its clock, home and estimator are not the
journal's, and it is not rejoined. A home that moved (PX4 sets home on arming) moves the
autopilot's local frame: the found targets' readings, kept in it, are moved with it.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from .journal import JournalDoc, JournalError, LoopState
from .link import CommandRejected, LinkError
from .preflight import ensure_failsafe

if TYPE_CHECKING:
    from .service import PolicyService

ON_GROUND = 1  # MAV_LANDED_STATE_ON_GROUND
#: "near where the journal left it": within this of the journal's last setpoint (m)
NEAR_M = 3.0
#: wall seconds to wait for a vehicle that has landed to disarm by itself before disarming it
DISARM_WAIT_S = 10.0
#: a vehicle whose telemetry never says whether it has landed counts as in the air above this (m)
IN_AIR_M = 1.0


@dataclass(frozen=True)
class Rejoined:
    """How the vehicle was found and taken back, for the operator and the log."""

    at_move: int
    how: str  # "in the air" or "took off again"
    mode_found: str
    armed_found: bool
    #: from the journal's last setpoint when found (m); None without a position
    off_setpoint_m: float | None
    #: simulated seconds from the journal's save to the re-anchored first decision
    gap_s: float
    t_k: float
    home_moved_m: float

    def to_dict(self) -> dict:
        return asdict(self)


def rejoin(service: PolicyService, doc: JournalDoc, loop: LoopState, timeout: float = 60.0) -> Rejoined:
    """Find the vehicle, check it is on the journal's timeline, take it back into the dialect's
    guided mode (PX4 OFFBOARD, ArduPilot GUIDED)
    in the air (taking off again if it has landed), and return how, with the first decision's
    re-anchored time (`Rejoined.t_k`), for `PolicyService.run(resume=...)`."""
    link, intake, spec = service.link, service.intake, service.spec
    tel = link.telemetry
    link.wait_heartbeat(timeout)
    link.request_streams()  # ArduPilot streams only what is asked for
    # a vehicle its failsafe would leave flying is not rejoined either (or made safe: --set-failsafe)
    ensure_failsafe(link, link.conn.mav.srcSystem, spec.set_failsafe)
    link.wait_for(lambda: bool(tel.home) and tel.gps.get("fix_type", 0) >= 3 and bool(intake.local_history),
                  timeout, "GPS fix, home position and the autopilot's position estimate")
    saved_t = float(doc.meta["vehicle"]["sim_time_s"])
    clock = intake.local_history[-1][0]  # the vehicle's clock now, by this link (the intake's own holds the journal's)
    if clock + 1e-6 < saved_t:
        raise JournalError(
            f"the vehicle's clock is at {clock:.1f} s, before {saved_t:.1f} s when {doc.path} was "
            "written: the autopilot has restarted since, and the journal's times, home and GPS bias are not "
            "its; a restarted autopilot is not rejoined: start a new search (another --out)")
    home_moved = _follow_home(service, doc)
    service.pilot.set_search_height()  # over this home (a take-off below fixes it again)
    try:  # whether it has landed: EXTENDED_SYS_STATE, else its height
        link.wait_for(lambda: tel.landed_state != 0, 3.0, "landed state")
        in_air = tel.armed and tel.landed_state != ON_GROUND
    except LinkError:
        in_air = tel.armed and -tel.local.get("d", 0.0) > IN_AIR_M
    mode, armed = tel.mode, tel.armed
    here = np.array([tel.local.get("n", math.nan), tel.local.get("e", math.nan)])
    sp = doc.meta["vehicle"].get("setpoint_local")
    off = None
    if sp is not None and np.all(np.isfinite(here)):
        off = float(np.hypot(*(here - (np.asarray(sp, float) + home_moved))))
    if in_air:
        how = "in the air"
    else:
        _take_off_again(service, timeout)
        how = "took off again"
        here = np.array([tel.local["n"], tel.local["e"]])
    _hand_over(service, here)
    period = spec.decision_period_s
    n = max(math.ceil((intake.sim_time_s + period - loop.t_k) / period - 1e-9), 0)
    t_k = loop.t_k + n * period
    return Rejoined(loop.move, how, mode, armed, None if off is None else round(off, 2),
                    round(t_k - saved_t, 3), t_k, round(float(np.hypot(*home_moved)), 3))


def _follow_home(service: PolicyService, doc: JournalDoc) -> np.ndarray:
    """Home now against the journal's: the autopilot's local frame moved by the difference
    (north, east m), and the found targets' readings in it are moved with it. Returns it."""
    old = doc.meta["vehicle"].get("home") or {}
    if not old:
        return np.zeros(2)
    origin = service.spec.origin
    was = origin.geodetic_to_ned(old["lat"], old["lon"], old["alt"])[:2]
    now = service.intake.home_in_field()[:2]
    shift = np.asarray(was - now, dtype=float)  # local = field - home
    if float(np.hypot(*shift)) > 1e-3:
        found = service.found
        found._found_at = [(t, np.asarray(p) + shift) for t, p in found._found_at]
    return shift


def _take_off_again(service: PolicyService, timeout: float) -> None:
    """A landed vehicle: wait for it to disarm (or disarm it), arm, climb to the search height."""
    link, spec = service.link, service.spec
    tel = link.telemetry
    if tel.armed:
        try:
            link.wait_for(lambda: not tel.armed, DISARM_WAIT_S, "the landed vehicle to disarm")
        except LinkError:
            link.disarm()
    dialect = link.require_dialect()
    if dialect.guided_before_arming:  # ArduCopter arms and takes off in GUIDED
        link.set_mode(dialect.guided_mode)
    _arm_after_failsafe(link, dialect.heartbeat_feeds_failsafe)
    service.pilot.set_search_height()
    link.takeoff(dialect.takeoff_altitude(tel.home["alt"], spec.altitude_m))
    link.wait_for(lambda: service.pilot.climbed(spec.altitude_m - 0.4), timeout, f"take-off to {spec.altitude_m} m")


def _arm_after_failsafe(link, by_heartbeat: bool, wait_s: float = 15.0) -> None:
    """Arm a vehicle the dead companion's failsafe brought down: ArduCopter refuses ("Arm: GCS
    failsafe on", measured on the real one) until its GCS failsafe has heard the watched
    system again, which this companion's heartbeats clear within a second or two."""
    end = time.monotonic() + wait_s
    while True:
        if by_heartbeat:
            link.heartbeat_now()
        try:
            link.arm(retry_s=10.0)
            return
        except CommandRejected as e:
            if "failsafe" not in e.reason.lower() or time.monotonic() > end:
                raise
            time.sleep(0.5)


def _hand_over(service: PolicyService, here: np.ndarray) -> None:
    """Start the setpoint stream where the vehicle is, at the search height, and take the
    dialect's guided mode: the tail of `Pilot.take_off`, from wherever the vehicle is. With
    altitude levels, at the journaled level's height (the next frame waits for it to settle)."""
    if service.height.levels > 1:
        service.pilot.change_height(service.height.altitude_m())
    service.pilot.start_stream(here)
