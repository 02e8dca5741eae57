"""Flying: take-off, the OFFBOARD setpoint stream, the legs to each cell, landing.

Its own part of the service because the setpoint stream is a thread of its own that must not
outlive the decision loop: the loop promises its next step within a deadline (`expect`), and
a loop silent past it stops the stream so the vehicle's offboard-loss failsafe takes over.
Setpoints are sent in the autopilot's local frame, shifted by the registered GPS bias so the
camera is truly over the cell it is meant to be over.
"""

from __future__ import annotations

import logging
import math
import threading
import time

import numpy as np

from sim.gridworld import cell_to_ned

from .camera import CameraNotFound, FrameSource
from .estimator import GpsEstimator
from .fence import BreachWatch, ensure_fence
from .link import CommandRejected, LinkError, VehicleLink, mavlink
from .preflight import ensure_failsafe
from .registration import Registration
from .search_data import SearchLog, SearchSpec
from .telemetry import TelemetryIntake

log = logging.getLogger(__name__)
DECISION_DEADLINE_S = 5.0  # a decision (map update, policy) that takes longer is a hung loop
FRAME_DEADLINE_S = 20.0  # a frame request, all its resends included
#: the take-off's instants (simulated s): arm this long after the later of the schedule's
#: origin t_ref and the launch window's end, climb half a second later, and hand over to
#: OFFBOARD and the first leg CLIMB_S after that (a 3.5 m climb takes ~3 s). With the default
#: 4 s period the first decision, a period after the hand-over, is at t_ref + 12 s, as before
ARM_AFTER_S = 0.5
TAKEOFF_AFTER_ARM_S = 0.5
CLIMB_S = 5.0
#: simulated seconds after the hand-over by which the climb must be half done (a 3.5 m climb
#: takes ~3 s; the take-off command itself waits for the frame of its instant, late on a
#: loaded machine while a real autopilot flies on)
CLIMB_GRACE_S = 10.0
#: ... and wall seconds it is waited for at least
CLIMB_WAIT_MIN_S = 3.0
#: the first leg's setpoint goes out this long after the hand-over (held there too)
LEG_AFTER_S = 0.5
#: wall seconds to wait for a frame asked for ahead before asking again
FRAME_WAIT_S = 5.0
#: asks for OFFBOARD while it is refused for want of a fresh setpoint
OFFBOARD_TRIES = 5


class Pilot:
    """Flies the vehicle for the decision loop: take-off onto the schedule's clock, one
    setpoint per leg (streamed while the loop keeps its promises), landing."""

    def __init__(self, link: VehicleLink, spec: SearchSpec, estimator: GpsEstimator,
                 intake: TelemetryIntake, registration: Registration, search_log: SearchLog,
                 frames: FrameSource) -> None:
        self.link, self.spec, self.estimator, self.frames = link, spec, estimator, frames
        self.intake, self.registration, self.log = intake, registration, search_log
        self._setpoint: np.ndarray | None = None  # local NED (autopilot frame)
        self._setpoint_lock = threading.Lock()
        self._stream_stop = threading.Event()
        self._alive_until = float("inf")  # the decision loop's deadline (see expect)
        self.t_ref: float | None = None  # the schedule's origin on the simulated clock
        #: where take_off leaves the vehicle held, for the first leg and OFFBOARD
        self.t_offboard: float | None = None
        #: the fence's watch on the vehicle's position (a spec with a fence; fence.BreachWatch)
        self.fence_watch: BreachWatch | None = None
        #: the search height in the autopilot's local frame (down, m): fixed at take-off from
        #: home's height there (TelemetryIntake.home_down_local)
        self.search_d = -spec.altitude_m
        #: home's height in the local frame (down, m) the search height is counted from
        self.home_d = 0.0

    def set_search_height(self) -> float:
        """Fix the search height over home in the local frame (before a take-off, and when a
        resumed search rejoins); returns it (down, m)."""
        self.home_d = self.intake.home_down_local()
        self.search_d = self.home_d - self.spec.altitude_m
        return self.search_d

    def change_height(self, altitude_m: float) -> float:
        """Fly the search at altitude_m over home from the next setpoint on (an altitude level's
        height, autopilot_bridge.height); counted from the home height take-off fixed, so every
        level stands on the same ground. Returns the new search height (down, m)."""
        self.search_d = self.home_d - altitude_m
        return self.search_d

    def climbed(self, above_m: float) -> bool:
        """Whether the autopilot's estimate is more than above_m over home."""
        return self.link.telemetry.local.get("d", 0.0) < self.search_d + self.spec.altitude_m - above_m

    def expect(self, seconds: float) -> None:
        """The decision loop promises its next step within `seconds`; past that it is hung and
        the setpoint stream stops, so the vehicle's offboard-loss failsafe takes over (a
        stream that outlives its decision loop would hold the vehicle in OFFBOARD for ever)."""
        self._alive_until = time.monotonic() + seconds

    def _stream_setpoints(self) -> None:
        """The setpoint thread: repeats the latest setpoint at 20 Hz (PX4 leaves OFFBOARD when
        they stop) while the decision loop keeps its promise."""
        starved = False
        by_heartbeat = self.link.require_dialect().heartbeat_feeds_failsafe
        while not self._stream_stop.is_set():
            if time.monotonic() > self._alive_until:
                if not starved:
                    log.warning("decision loop silent past its deadline: setpoints %sstopped, the vehicle's "
                                "companion-loss failsafe takes over", "and heartbeats " if by_heartbeat else "")
                    if by_heartbeat:
                        self.link.silence_heartbeats(True)
                starved = True
            elif self._setpoint is not None:
                if starved and by_heartbeat:
                    self.link.silence_heartbeats(False)
                starved = False
                with self._setpoint_lock:  # never resend an old setpoint after a new one
                    self.link.set_position_ned(*self._setpoint)
            time.sleep(0.05)

    def fly_to(self, cell: np.ndarray) -> np.ndarray:
        """Send the new setpoint at once (the stream repeats it); returns it in local NED. The
        autopilot flies its GPS-fed estimate (truth + bias): the setpoint is shifted by the
        estimated bias so the vehicle is truly over the cell's centre."""
        local = self.intake.field_to_local(cell_to_ned(cell))
        if self.spec.register:
            local = local + self.estimator.bias_ned[:2]
        return self.set_local(local)

    def set_local(self, local: np.ndarray) -> np.ndarray:
        """Send a setpoint given in the autopilot's local (north, east) at once, logged, and
        renew the loop's promise; back to OFFBOARD if the autopilot left it. With a fence, a
        position seen outside it stops here (FenceBreached) instead."""
        if self.fence_watch is not None:
            self.fence_watch.check()  # outside the fence: no leg that would undo its action
        self.log.setpoints_local.append([round(float(v), 4) for v in local])
        self.expect(DECISION_DEADLINE_S)
        with self._setpoint_lock:
            self._setpoint = np.array([local[0], local[1], self.search_d])
            self.link.set_position_ned(*self._setpoint)
        if self.link.telemetry.mode != self.link.require_dialect().guided_mode:
            self._enter_offboard()  # the first leg, or the autopilot dropped out
        return local

    def _enter_offboard(self) -> None:
        """The mode setpoints are flown in (PX4 OFFBOARD, ArduPilot GUIDED). PX4 refuses
        OFFBOARD (temporarily) until it has a fresh setpoint: the one just sent can be lost on a
        lossy radio, so the stream's next ones are waited for and the switch asked again (20 %
        loss: the first ask was refused in one search in ten)."""
        mode = self.link.require_dialect().guided_mode
        for attempt in range(OFFBOARD_TRIES):
            try:
                self.link.set_mode(mode)
                return
            except CommandRejected as e:
                if e.result != mavlink.MAV_RESULT_TEMPORARILY_REJECTED or attempt == OFFBOARD_TRIES - 1:
                    raise
                time.sleep(0.3)  # the stream sends six setpoints meanwhile

    # -- the mission ---------------------------------------------------------------------
    def take_off(self, timeout: float = 60.0) -> None:
        """Ask for the dialect's streams, check the companion-loss failsafe (preflight.py), wait
        until the autopilot is ready (its dialect says what that takes), fix the schedule's
        origin t_ref, register the launch point, arm half a second after the later of t_ref and
        the launch window's end (t_arm; ArduCopter in GUIDED first; before it, the field's fence
        when the spec has one: fence.py, FenceRefused stops here), take off half a second
        later, enter the dialect's guided mode at the hover CLIMB_S after that (`t_offboard`),
        and return with the vehicle held LEG_AFTER_S later, for the decision loop's first leg.

        Each command is sent while a companion-lockstep vehicle holds its clock at a capture
        asked for ahead (it holds at a timed capture until the companion's next command), so it
        executes at that simulated instant whatever the wall clock did. Sent on wall-clock
        timing (as before), the climb began a few milliseconds of simulated time apart from run
        to run, and one flight in twenty flew a different search from the same seed. Without
        lockstep the captures only wait for their instants."""
        link = self.link
        link.wait_heartbeat()
        dialect = link.require_dialect()
        self.log.preflight.append(f"autopilot: {dialect.name}")
        self.log.preflight += link.request_streams()
        # before anything flies: a vehicle a dead companion would leave in the air is refused
        # (or, --set-failsafe, made safe); while the fixes of the launch window come in
        self.log.preflight += ensure_failsafe(link, link.conn.mav.srcSystem, self.spec.set_failsafe, log.warning)
        link.wait_for(lambda: dialect.not_ready(link.telemetry) is None, timeout,
                      lambda: dialect.not_ready(link.telemetry) or "readiness")
        link.wait_for(lambda: self.intake.has_fixes() or self.estimator.initialised, timeout,
                      "a position estimate")
        # the schedule's origin: the lattice point after the first fix this link heard (0 s when
        # the link was up before the vehicle started), not "now", which depends on how long
        # this process took to get going; the start cell comes from the fixes up to it
        period = self.spec.decision_period_s
        anchor = self.intake.first_fix_t
        if self.intake.sim_time_s - anchor > period:
            # readiness came long after the first fix (ArduCopter's EKF: ~40 s): the schedule
            # starts from now, not from a past the vehicle has left behind
            anchor = self.intake.sim_time_s
        self.t_ref = period * math.ceil((anchor + 0.5) / period)
        t_arm = max(self.t_ref, self.registration.launch_window()[1]) + ARM_AFTER_S
        t_climb = t_arm + TAKEOFF_AFTER_ARM_S
        self.t_offboard = t_climb + CLIMB_S
        t_leg = self.t_offboard + LEG_AFTER_S
        timed = self._ask_ahead((t_arm, t_climb, self.t_offboard, t_leg))
        self.registration.register_launch()  # its window ends before t_arm
        if self.spec.fence is not None:
            # the field's fence on the autopilot, verified, or no take-off: once the schedule is
            # fixed (a lockstep vehicle holds at t_arm meanwhile), so the transfer's wall time
            # cannot move it (before t_ref it did: seed 2 flew 34 moves, then 44)
            self.log.preflight += ensure_fence(link, self.spec.fence, log.warning)
            self.fence_watch = BreachWatch(link, self.spec.fence)
        if dialect.heartbeat_feeds_failsafe:  # heard before arming: the failsafe watches from here
            link.heartbeat_now()
        if dialect.guided_before_arming:  # ArduCopter arms and takes off in GUIDED
            link.set_mode(dialect.guided_mode)
        if timed:
            self._held_at(t_arm, timeout)
        link.arm()
        if timed:
            self._held_at(t_climb, timeout)
        self.set_search_height()
        link.takeoff(dialect.takeoff_altitude(link.telemetry.home["alt"], self.spec.altitude_m))
        if timed:
            self._held_at(self.t_offboard, timeout)
            # half-way up by then (OFFBOARD's setpoint finishes the last decimetres), judged on
            # the vehicle's clock (a real autopilot is not held by the companion: on a loaded
            # machine 3 wall seconds were less than the climb) and never in under 3 wall seconds
            # (a take-off command resent over a lossy radio lands seconds of vehicle time late)
            half, late, since = self.spec.altitude_m / 2, self.t_offboard + CLIMB_GRACE_S, time.monotonic()
            link.wait_for(lambda: self.climbed(half)
                          or (self.intake.sim_time_s > late and time.monotonic() - since > CLIMB_WAIT_MIN_S),
                          timeout, "the take-off's climb")
            if not self.climbed(half):
                raise LinkError(f"take-off: not above {half:.1f} m by {late:.1f} s (simulated): {self._climb_state()}")
        else:
            link.wait_for(lambda: self.climbed(self.spec.altitude_m - 0.4), timeout,
                          f"take-off to {self.spec.altitude_m} m")
            self.t_offboard = max(self.t_offboard, self.intake.sim_time_s)
        if self.registration.launch_registered:
            # the climb's fixes are left out: the registered launch predicted forward stands
            # (the hover after the climb refines it before the first decision)
            self.intake.drop_fixes_until(self.t_ref)
        else:
            self.intake.fuse_until(self.t_ref)
        # OFFBOARD at the hover, so a companion that hangs from here on leaves a vehicle whose
        # offboard-loss failsafe brings it home (the stream stops at the loop's deadline)
        here = self.intake.local_at(self.t_offboard) if timed else None
        if here is None:
            here = np.array([link.telemetry.local["n"], link.telemetry.local["e"]])
        self.start_stream(here)
        if timed:
            self._held_at(t_leg, timeout)  # the decision loop's first leg starts here

    def _climb_state(self) -> str:
        """Where a stopped take-off left the vehicle, for the operator: height over home, mode,
        armed, and what the autopilot last said."""
        tel = self.link.telemetry
        d, home_d = tel.local.get("d", math.nan), self.search_d + self.spec.altitude_m
        said = " / ".join(tel.statustext[-4:]) or "nothing"
        return (f"{home_d - d:.2f} m over home (local down {d:.2f}, home at {home_d:.2f}), mode {tel.mode}, "
                f"{'armed' if tel.armed else 'disarmed'}; it said: {said}")

    def start_stream(self, here: np.ndarray) -> None:
        """Hold the vehicle at `here` (local north, east) at the search height: the setpoint
        sent at once, then streamed by its thread under the decision loop's deadline, and the
        dialect's guided mode taken (after take-off, and when a resumed search rejoins)."""
        with self._setpoint_lock:
            self._setpoint = np.array([here[0], here[1], self.search_d])
            self.link.set_position_ned(*self._setpoint)
        self.expect(DECISION_DEADLINE_S)
        threading.Thread(target=self._stream_setpoints, daemon=True, name="setpoints").start()
        self._enter_offboard()

    def _ask_ahead(self, times: tuple[float, ...]) -> bool:
        """Ask for captures at these simulated instants, long before the clock gets there.
        False when the vehicle has no camera (it answers UNSUPPORTED): then the take-off is
        flown on command timing, as a vehicle without lockstep flies it anyway."""
        if not self.frames.timed_captures:  # a video source: its frames come as they are taken
            return False
        try:
            for t in times:
                self.frames.ask(t)
        except CommandRejected as e:
            if e.result != mavlink.MAV_RESULT_UNSUPPORTED:
                raise
            log.info("no timed captures on this vehicle (%s): take-off on command timing", e)
            return False
        except CameraNotFound as e:  # a camera-less vehicle: flown as one without lockstep
            log.info("%s: take-off on command timing", e)
            return False
        return True

    def _held_at(self, t: float, timeout: float) -> None:
        """Wait for the frame captured at simulated time t (asked for ahead): a lockstep vehicle
        holds its clock there until this companion's next command. Asked again only when it
        does not come (a lossy link lost the ask or the frame): asking releases a hold."""
        frame, _ = self.frames.wait(t, FRAME_WAIT_S)
        if frame is None:
            frame, _ = self.frames.capture(t)
        if frame is None:
            raise LinkError(f"no camera frame at {t:.1f} s (simulated) during take-off")

    def stop_setpoints(self) -> None:
        """Stop streaming OFFBOARD setpoints (before handing the vehicle to an AUTO mode)."""
        self._stream_stop.set()

    def land(self, timeout: float = 60.0) -> None:
        """Stop the setpoint stream, land and wait for the vehicle to disarm."""
        self._stream_stop.set()
        self.link.land()
        self.link.wait_for(lambda: not self.link.telemetry.armed, timeout, "landing and disarm")
