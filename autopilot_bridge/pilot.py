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

from .estimator import GpsEstimator
from .link import VehicleLink
from .registration import Registration
from .search_data import SearchLog, SearchSpec
from .telemetry import TelemetryIntake

log = logging.getLogger(__name__)
DECISION_DEADLINE_S = 5.0  # a decision (map update, policy) that takes longer is a hung loop
FRAME_DEADLINE_S = 20.0  # a frame request, all its resends included


class Pilot:
    """Flies the vehicle for the decision loop: take-off onto the schedule's clock, one
    setpoint per leg (streamed while the loop keeps its promises), landing."""

    def __init__(self, link: VehicleLink, spec: SearchSpec, estimator: GpsEstimator,
                 intake: TelemetryIntake, registration: Registration, search_log: SearchLog) -> None:
        self.link, self.spec, self.estimator = link, spec, estimator
        self.intake, self.registration, self.log = intake, registration, search_log
        self._setpoint: np.ndarray | None = None  # local NED (autopilot frame)
        self._setpoint_lock = threading.Lock()
        self._stream_stop = threading.Event()
        self._alive_until = float("inf")  # the decision loop's deadline (see expect)
        self.t_ref: float | None = None  # the schedule's origin on the simulated clock

    def expect(self, seconds: float) -> None:
        """The decision loop promises its next step within `seconds`; past that it is hung and
        the setpoint stream stops, so the vehicle's offboard-loss failsafe takes over (a
        stream that outlives its decision loop would hold the vehicle in OFFBOARD for ever)."""
        self._alive_until = time.monotonic() + seconds

    def _stream_setpoints(self) -> None:
        """The setpoint thread: repeats the latest setpoint at 20 Hz (PX4 leaves OFFBOARD when
        they stop) while the decision loop keeps its promise."""
        starved = False
        while not self._stream_stop.is_set():
            if time.monotonic() > self._alive_until:
                if not starved:
                    log.warning("decision loop silent past its deadline: setpoints stopped, the vehicle's "
                                "offboard-loss failsafe takes over")
                starved = True
            elif self._setpoint is not None:
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
        renew the loop's promise; back to OFFBOARD if the autopilot left it."""
        self.log.setpoints_local.append([round(float(v), 4) for v in local])
        self.expect(DECISION_DEADLINE_S)
        with self._setpoint_lock:
            self._setpoint = np.array([local[0], local[1], -self.spec.altitude_m])
            self.link.set_position_ned(*self._setpoint)
        if self.link.telemetry.mode != "OFFBOARD":  # the autopilot dropped out (e.g. lost setpoints)
            self.link.set_mode("OFFBOARD")
        return local

    # -- the mission ---------------------------------------------------------------------
    def take_off(self, timeout: float = 60.0) -> None:
        """Wait for GPS and home, fix the schedule's origin t_ref, register the launch point,
        climb, and start the setpoint stream in OFFBOARD at the hover."""
        link = self.link
        link.wait_heartbeat()
        link.wait_for(lambda: bool(link.telemetry.home) and link.telemetry.gps.get("fix_type", 0) >= 3,
                      timeout, "GPS fix and home position")
        link.wait_for(lambda: self.intake.has_fixes() or self.estimator.initialised, timeout,
                      "a position estimate")
        # the schedule's origin: the lattice point after the first fix this link heard (0 s when
        # the link was up before the vehicle started), not "now", which depends on how long
        # this process took to get going; the start cell comes from the fixes up to it
        period = self.spec.decision_period_s
        self.t_ref = period * math.ceil((self.intake.first_fix_t + 0.5) / period)
        self.registration.register_launch()
        link.arm()
        link.takeoff(link.telemetry.home["alt"] + self.spec.altitude_m)
        link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -(self.spec.altitude_m - 0.4),
                      timeout, f"take-off to {self.spec.altitude_m} m")
        self.intake.wait_sim_time(self.t_ref, timeout)
        if self.registration.launch_registered:
            # the climb is flown on wall-clock command timing (AUTO.TAKEOFF holds the estimate
            # of the instant it was commanded): its fixes would leak centimetres of that timing
            # into the bias the setpoints are shifted by. The registered launch predicted
            # forward stands instead; fixes resume with the first leg.
            self.intake.drop_fixes_until(self.t_ref)
        else:
            self.intake.fuse_until(self.t_ref)
        local = link.telemetry.local
        self._setpoint = np.array([local["n"], local["e"], -self.spec.altitude_m])
        self.expect(DECISION_DEADLINE_S)
        threading.Thread(target=self._stream_setpoints, daemon=True, name="setpoints").start()
        time.sleep(0.3)  # PX4 wants a setpoint stream before OFFBOARD
        link.set_mode("OFFBOARD")

    def stop_setpoints(self) -> None:
        """Stop streaming OFFBOARD setpoints (before handing the vehicle to an AUTO mode)."""
        self._stream_stop.set()

    def land(self, timeout: float = 60.0) -> None:
        """Stop the setpoint stream, land and wait for the vehicle to disarm."""
        self._stream_stop.set()
        self.link.land()
        self.link.wait_for(lambda: not self.link.telemetry.armed, timeout, "landing and disarm")
