"""Quiet ticks: a fleet vehicle's 50 Hz tick without the per-vehicle Python (issue 13).

Most ticks of a hovering or cruising vehicle change nothing but its battery: no GPS fix is due
(5 Hz), no telemetry (13 of 50 ticks send), no failsafe timer runs out, the fence is not
near. Yet the full tick (MavlinkVehicle.tick) costs ~10 us a vehicle in Python whatever it
does, 0.5 ms of a 100-vehicle fleet's 1 ms budget per vehicle-second at 10x real time.

After each full tick a vehicle states how long it stays quiet (`QuietPlan`); `QuietFleet` then
decides every tick with numpy over the fleet which vehicles are still quiet, and steps those
with the same battery arithmetic on arrays (the same IEEE operations in the same order: the
same numbers), taking a due GPS fix first and handing due telemetry to the fleet last, as the
full tick orders them; the others take the full tick (without a fix already taken). A vehicle
is woken for a full tick by:
- anything it received (the fleet marks a served vehicle awake before its next tick);
- its airframe arming, disarming, taking off or landing (the failsafes and the flying change);
- simulated time reaching its next camera frame, or its offboard setpoint timeout (in simulated
  time; once past it, the vehicle stays awake until setpoints come or the failsafe fires);
- the wall clock reaching its data-link-loss timeout;
- its battery about to cross the next failsafe threshold (the tick that crosses is full);
- its position estimate leaving the geofence, or reaching its take-off height.
Modes that act on every tick (mission, return, position control), velocity control, a geofence
hold, a polygon fence to enforce, an offboard-loss hold, a mission or fence upload, queued frames, injected failures and a vehicle on
another clock than the fleet's are never quiet. tests/sim/mavlink/test_quiet.py flies a fleet
both ways and compares every vehicle's state, battery, mode, failsafes and datagrams tick by tick.

Code that changes a fleet vehicle other than over MAVLink (a test calling its methods) between
runs is seen at the next `SitlFleet.run`, which wakes every vehicle; during a run, call
`SitlFleet.wake(i)`.
"""

from __future__ import annotations

import logging
import math
import time
import traceback
from dataclasses import dataclass

import numpy as np

from sim.vehicle.fleet import ArrayState

from .battery import CELLS, GROUND_DRAW, V_CHARGED, V_EMPTY

#: modes whose flying does nothing on a tick, or (take-off) only once the estimate is within
#: 0.3 m of the target height (flying.py `_fly` acts in the others every tick)
QUIET_MODES = frozenset({"AUTO.LOITER", "OFFBOARD", "AUTO.LAND", "AUTO.TAKEOFF"})
EPS = 1e-9  # the vehicle's own due test: due when t + 1e-9 >= the due time
log = logging.getLogger(__name__)


@dataclass
class QuietPlan:
    """How long a vehicle's ticks stay quiet, and what a quiet tick needs to know."""

    until_t: float  # quiet while t + EPS < until_t (simulated)
    until_wall: float  # ... and the wall clock is <= until_wall
    armed: bool  # the airframe's state the plan was made in
    landed: bool
    battery_floor: float  # quiet while the drained battery stays above it
    endurance_s: float
    min_remaining: float
    fence_h: float  # geofence limits (m)
    fence_v: float
    takeoff_z: float = math.nan  # AUTO.TAKEOFF: the target's down coordinate (loiter within 0.3 m)


class QuietVehicle:
    """A mixin of MavlinkVehicle: `quiet_plan()` after a full tick."""

    def quiet_plan(self) -> QuietPlan | None:
        """None: the next tick must be full."""
        s = self.model.state
        if (self.mode not in QUIET_MODES or self.fix is None or self.failures or self._velocity_control
                or self._fence_hold or self._obl_since is not None or self.missions.incoming is not None
                or self.battery.failed or self.fences.zones or self._fence_transfer()):
            return None
        p = self.params
        # a GPS fix or telemetry due on a quiet tick is taken or sent by it (QuietFleet.tick);
        # a component's (a camera's heartbeat, a frame) is not: a full tick then
        until = math.inf
        for c in self.components:
            c_until = c.quiet_until()
            if c_until is None:
                return None
            until = min(until, c_until)
        until_wall, floor = math.inf, -math.inf
        if s.armed and not s.landed:  # the failsafes run
            if self.mode == "OFFBOARD":  # stale only once stale in simulated time too (offboard_fresh)
                until = min(until, self._offboard_sim_t + p["COM_OF_LOSS_T"] - 1e-6)
            if self._gcs_heartbeat_wall is not None and not self._dll_active:
                until_wall = self._gcs_heartbeat_wall + p["COM_DL_LOSS_T"]
            floor = (p["BAT_LOW_THR"], p["BAT_CRIT_THR"], p["BAT_EMERGEN_THR"], -math.inf)[self._bat_level]
        takeoff_z = float(self._target[2]) if self.mode == "AUTO.TAKEOFF" and self._target is not None else math.nan
        return QuietPlan(until, until_wall, s.armed, s.landed, floor, p["UAVS_BAT_ENDUR_S"],
                         p["SIM_BAT_MIN_PCT"] / 100.0, p["GF_MAX_HOR_DIST"], p["GF_MAX_VER_DIST"], takeoff_z)

    def _fence_transfer(self) -> bool:
        """A fence upload under way (its re-requests run in the full tick)."""
        fences = self.missions.fences
        return fences is not None and fences.incoming is not None


class QuietFleet:
    """The fleet's side: every vehicle's plan as arrays, and the quiet ticks on them."""

    def __init__(self, sitls: list, enabled: bool = True, clock=time.monotonic, world=None) -> None:
        """enabled False: every tick full (as before quiet ticks; the tests compare both).
        clock: the vehicles' wall clock (a vehicle on another clock is never quiet). world: the
        fleet's airframes; when its states read their battery from its arrays (ArrayState),
        quiet ticks write those arrays at once."""
        self.sitls, self.enabled, self.clock = sitls, enabled, clock
        self.states = [s.model.state for s in sitls]  # a fleet's states live as long as it does
        self.world = world if world is not None and all(
            isinstance(st, ArrayState) and st._f is world for st in self.states) else None
        n = len(sitls)
        self.awake = np.ones(n, dtype=bool)  # must take a full tick next
        self.until_t = np.full(n, -math.inf)
        self.until_wall = np.full(n, -math.inf)
        self.armed = np.zeros(n, dtype=bool)
        self.landed = np.zeros(n, dtype=bool)
        self.floor = np.full(n, math.inf)
        self.endurance = np.ones(n)
        self.min_remaining = np.zeros(n)
        self.remaining = np.zeros(n)  # the battery, kept here between full ticks
        self.err = np.zeros((n, 3))  # the estimate's error (changes on a GPS fix: a full tick)
        self.fence = np.zeros((n, 2))
        self.takeoff_z = np.full(n, math.nan)
        self.gps_next = np.zeros(n)  # each receiver's next fix (simulated s)
        self.t_prev = None  # the last tick's simulated time
        self.quiet_ticks = self.full_ticks = 0  # vehicle-ticks of each kind so far

    def wake(self, i: int) -> None:
        self.awake[i] = True

    def tick(self, t: float, positions: np.ndarray, armed: np.ndarray, landed: np.ndarray) -> None:
        """Every vehicle's MAVLink tick at simulated time t: full ones for the vehicles awake,
        quiet ones for the rest. positions: (N, 3) true NED positions after the physics step;
        armed, landed: (N,) the airframes' flags."""
        dt = 0.0 if self.t_prev is None else max(t - self.t_prev, 0.0)
        self.t_prev = t
        quiet = ~self.awake & (t + EPS < self.until_t) & (armed == self.armed) & (landed == self.landed)
        sampled = np.zeros(0, dtype=np.int64)
        if quiet.any():
            quiet &= self.clock() <= self.until_wall
            # a fix due: taken first, as the full tick takes it first (the estimate moves with it)
            sampled = np.flatnonzero(quiet & (t + EPS >= self.gps_next))
            for i in sampled.tolist():
                v = self.sitls[i].vehicle
                try:
                    v.sample_gps(t)
                except Exception:  # as Sitl.tick: recorded, and the vehicle stays on its link
                    self._failed(i, t)
                self.err[i], self.gps_next[i] = v.gps.estimate_error, v.gps._next
            flying = armed & ~landed
            est = positions + self.err  # the autopilot's estimate, as MavlinkVehicle.estimate
            # inside by a micrometre (np.hypot and math.hypot may differ in the last bit): at the
            # fence itself the full tick decides
            inside = ((np.hypot(est[:, 0], est[:, 1]) <= self.fence[:, 0] - 1e-6)
                      & (-est[:, 2] <= self.fence[:, 1] - 1e-6))
            quiet &= inside | ~flying
            # taking off: loiters once within 0.3 m of the target height (a micrometre's margin)
            quiet &= ~(armed & (np.abs(est[:, 2] - self.takeoff_z) < 0.3 + 1e-6))  # NaN: not taking off
            # Battery.step on arrays: the same operations in the same order
            r = self.remaining
            drains = armed & (self.endurance > 0) & (r > self.min_remaining)
            drained = r - dt / self.endurance * np.where(flying, 1.0, GROUND_DRAW)
            new_r = np.where(drains, np.maximum(np.maximum(self.min_remaining, drained), 0.0), r)
            quiet &= new_r > self.floor  # the tick that crosses a failsafe threshold is full
            idx = np.flatnonzero(quiet)
            self.quiet_ticks += len(idx)
            r_q = new_r[idx]
            self.remaining[idx] = r_q
            volts = CELLS * (V_EMPTY + (V_CHARGED - V_EMPTY) * r_q)  # Battery.voltage
            sitls, states, world = self.sitls, self.states, self.world
            if world is not None:  # what the full tick writes in the state (the model drains its own)
                world.battery_remaining[idx], world.battery_voltage[idx] = r_q, volts
            for i, r_i, v_i in zip(idx.tolist(), r_q.tolist(), volts.tolist(), strict=True):
                sitl = sitls[i]
                v = sitl.vehicle
                sitl.t = v.t = t
                v.battery.remaining = r_i
                if world is None:
                    s = states[i]
                    s.battery_remaining, s.battery_voltage = r_i, v_i
                if t + EPS >= v._stream_next:  # telemetry due: what the full tick does last
                    try:
                        v._stream()
                    except Exception:
                        self._failed(i, t)
        full = np.flatnonzero(~quiet).tolist()
        self.full_ticks += len(full)
        done = set(sampled.tolist()) if len(sampled) else ()
        for i in full:
            sitl = self.sitls[i]
            sitl.tick(t, serve=False, sampled=i in done)  # a fix taken above is not taken twice
            self._plan(i, sitl.vehicle)

    def _failed(self, i: int, t: float) -> None:
        sitl = self.sitls[i]
        sitl.errors.append(traceback.format_exc())
        log.exception("SITL %d quiet tick failed at t=%.2f", sitl.cfg.instance, t)
        self.awake[i] = True

    def _plan(self, i: int, v) -> None:
        self.err[i], self.gps_next[i] = v.gps.estimate_error, v.gps._next
        plan = v.quiet_plan() if self.enabled and v.clock is self.clock else None
        if plan is None:
            self.awake[i] = True
            return
        self.awake[i] = False
        self.until_t[i], self.until_wall[i] = plan.until_t, plan.until_wall
        self.armed[i], self.landed[i] = plan.armed, plan.landed
        self.floor[i], self.endurance[i], self.min_remaining[i] = plan.battery_floor, plan.endurance_s, plan.min_remaining
        self.remaining[i] = v.battery.remaining
        self.fence[i] = plan.fence_h, plan.fence_v
        self.takeoff_z[i] = plan.takeoff_z
