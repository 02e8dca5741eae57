"""Telemetry intake: what the vehicle's MAVLink telemetry tells the companion about where it is.

Its own part of the service because it runs on the link's receive thread while the decision
loop reads it: GPS fixes are queued (stamped on the vehicle's simulated clock) and fused into
the position posterior only up to a decision's time, and the autopilot's LOCAL_POSITION_NED
estimate is kept as a history the settle check and the target memory look back into. Reading
by stamp, never by arrival, is what keeps a flight given its seed reproducible however fast the
link delivers.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from typing import Any

import numpy as np

from sim.gridworld.geodesy import HomePosition

from .estimator import GpsEstimator
from .link import LinkError, VehicleLink

#: "settled" for the camera at t_k: within SETTLED_M of the setpoint and slower than
#: SETTLED_SPEED by the autopilot's estimate. A hovering autopilot chases its GPS bias's jitter
#: (measured at t_k: up to 0.29 m and 0.41 m/s with the simulated receiver), so bounds near
#: those would slip the schedule at random and break reproducibility; a 2 m leg is over in ~2 s
SETTLED_M = 0.6
SETTLED_SPEED = 1.0
#: the settle check reads the latest LOCAL_POSITION_NED (10 Hz) stamped this long before t:
#: 0.5 s holds 5 samples, so a 20 %-lossy link leaves none 0.03 % of the time (0.25 s: 1-4 %)
SETTLED_LOOKBACK_S = 0.5
#: LOCAL_POSITION_NED samples kept (10 Hz of simulated time). A frame stamped t can arrive
#: long after t in simulated time: wall seconds of lossy resends times the speed-up (20 s of
#: FRAME_DEADLINE_S at 50x, where the vehicle starts to thin its streams, is 1000 s, 10k
#: samples). 400 (40 s) was shorter than one lossy frame at 10x: the samples around t were
#: gone when the frame came, the leg never "settled", and a 64-move search died.
LOCAL_KEEP = 10_000
#: the receiver's fix period (GPS_RAW_INT at 5 Hz)
FIX_PERIOD_S = 0.2
#: the autopilot's estimate's period (LOCAL_POSITION_NED at 10 Hz)
LOCAL_PERIOD_S = 0.1
#: wall-clock seconds a decision waits for the fix or estimate sample stamped before it
INPUT_WAIT_S = 0.5

#: a received GPS fix: (simulated time s, field NED m, eph m, epv m)
Fix = tuple[float, np.ndarray, float, float]
#: sd (m) of the autopilot's estimate as a measurement of position + bias (`fuse_reading`): its
#: EKF's residual beside the bias, and the vehicle's drift in the sample's age (<= 0.1 s). The
#: simulated autopilot's estimate is truth + bias exactly, so this is the sample's age; a real
#: EKF2 keeps decimetres. Chosen on flight seeds 0-59 (0.15: NEES 1.31 on 20-39, under its
#: interval; 0.05: 1.83 / 2.13 / 2.36 on 0-19 / 20-39 / 40-59, all inside)
READING_SD_M = 0.05
#: a LOCAL_POSITION_NED sample: (simulated time s, north, east, v north, v east)
LocalSample = tuple[float, float, float, float, float]
#: its vertical part, kept beside it: (simulated time s, down, v down)
DownSample = tuple[float, float, float]
#: "settled" in height for the camera at t_k where a decision changed the search height
#: (altitude levels): within SETTLED_DOWN_M of the commanded height and slower than
#: SETTLED_VSPEED vertically by the autopilot's estimate (the barometer holds decimetres; the
#: detector reads the height flown, so a decimetre left over only scales the frame by ~2 %)
SETTLED_DOWN_M = 0.4
SETTLED_VSPEED = 0.5


class TelemetryIntake:
    """GPS fixes and the autopilot's local estimate off the link, read by their stamps."""

    def __init__(self, link: VehicleLink, origin: HomePosition, estimator: GpsEstimator,
                 arrive_m: float) -> None:
        self.link, self.origin, self.estimator, self.arrive_m = link, origin, estimator, arrive_m
        self.last_gps_t = -1.0
        self._fixes: deque[Fix] = deque()  # received, not yet fused
        #: fixes left unfused because the filter had moved past their stamp (fuse_until)
        self.fixes_late = 0
        #: waits for a fix or an estimate sample stamped before a decision that gave up
        #: (INPUT_WAIT_S): lost on the link, or this computer too loaded to read it in time; the
        #: decision then used what had come, so it may differ from run to run
        self.input_waits_timed_out = 0
        self._fix_lock = threading.Lock()
        #: the autopilot's estimate, LOCAL_POSITION_NED
        self.local_history: deque[LocalSample] = deque(maxlen=LOCAL_KEEP)
        #: its height (down) and vertical speed at the same stamps: the height the camera flies
        #: at, read where the search height changes (altitude levels)
        self.down_history: deque[DownSample] = deque(maxlen=LOCAL_KEEP)
        self.sim_time_s = 0.0  # the latest simulated time any telemetry was stamped with
        self.first_fix_t: float | None = None
        self._dropped_until = -math.inf
        link.add_handler(self._on_message)

    # -- frames: field NED (origin = cell (0,0)) vs the autopilot's local NED (origin = home) --
    def home_in_field(self) -> np.ndarray:
        """Home (HOME_POSITION), the launch point, in the field frame."""
        h = self.link.telemetry.home
        return self.origin.geodetic_to_ned(h["lat"], h["lon"], h["alt"])

    def local_origin_in_field(self) -> np.ndarray:
        """The origin of the autopilot's local frame (LOCAL_POSITION_NED, the setpoints) in the
        field frame: GPS_GLOBAL_ORIGIN where the vehicle says it (PX4's and ArduPilot's EKFs
        set it at their first fix, which need not be home), else home less home's own local
        position (HOME_POSITION.x/y/z: PX4 sends GPS_GLOBAL_ORIGIN only when the origin changes,
        so a companion that connects after the EKF's first fix never hears it; taking home for
        the origin there put every estimate the home's 1-2 m offset away from where PX4 meant it;
        our SITL's home is its origin, x/y/z 0)."""
        o = self.link.telemetry.local_origin
        if not o:
            h = self.link.telemetry.home
            return self.home_in_field() - np.array([h.get("x", 0.0), h.get("y", 0.0), h.get("z", 0.0)])
        return self.origin.geodetic_to_ned(o["lat"], o["lon"], o["alt"])

    def home_down_local(self) -> float:
        """Home's height in the autopilot's local frame (down, m): the ground the search height
        is counted from. PX4's EKF2 sets its origin's altitude from the GPS at its first fix
        and holds height on the barometer after, so the ground sat 0.4-0.8 m from the origin's
        z = 0 and a setpoint at d = -3.5 flew the camera 3.9-4.3 m up (measured, seed 3); home
        is where the vehicle stood. Our SITL's home is its origin: 0."""
        return float(self.home_in_field()[2] - self.local_origin_in_field()[2])

    def field_to_local(self, ne_field: np.ndarray) -> np.ndarray:
        off = self.local_origin_in_field()
        return np.array([ne_field[0] - off[0], ne_field[1] - off[1]])

    def _on_message(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "GPS_RAW_INT" and msg.fix_type >= 3 and msg.time_usec * 1e-6 > self.last_gps_t:
            t = msg.time_usec * 1e-6
            self.last_gps_t = t
            ned = self.origin.geodetic_to_ned(msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3)
            eph = msg.h_acc * 1e-3 if msg.h_acc else msg.eph * 1e-2
            epv = msg.v_acc * 1e-3 if msg.v_acc else msg.epv * 1e-2
            with self._fix_lock:
                self._fixes.append((t, ned, eph, epv))
                if self.first_fix_t is None:
                    self.first_fix_t = t
            self.sim_time_s = max(self.sim_time_s, t)
        elif kind == "LOCAL_POSITION_NED":
            t = msg.time_boot_ms * 1e-3
            self.local_history.append((t, msg.x, msg.y, msg.vx, msg.vy))
            self.down_history.append((t, msg.z, msg.vz))
            self.sim_time_s = max(self.sim_time_s, t)

    def has_fixes(self) -> bool:
        """Whether a fix has been received and not yet fused (or dropped)."""
        return bool(self._fixes)

    def fuse_until(self, t: float) -> None:
        """Fuse the received fixes stamped up to simulated time t, in order; later ones wait,
        so the posterior at a decision does not depend on how fast the link delivered. A fix
        stamped within half a fix period of t is left for the next decision: whether it has
        arrived with the frame of t is a race (the vehicle may hold its clock at t for the
        companion before or after sending it); the one before is waited for a little."""
        t = t - FIX_PERIOD_S / 2
        try:
            self.link.wait_for(lambda: self.last_gps_t > t - FIX_PERIOD_S + 1e-6, INPUT_WAIT_S, "")
        except LinkError:
            self.input_waits_timed_out += 1  # a fix lost on the link: fuse what came
        with self._fix_lock:
            due = []
            while self._fixes and self._fixes[0][0] <= t + 1e-6:
                due.append(self._fixes.popleft())
        now = self.estimator.time_s
        for ft, ned, eph, epv in due:
            if ft <= self._dropped_until + 1e-6:
                continue
            if now is not None and ft < now - 1e-9:
                # stamped before a position measurement already fused (a decision that fell
                # within half a fix period after it, as on a link that delays and reorders):
                # the filter does not run backwards, so it is left out
                self.fixes_late += 1
                continue
            self.estimator.update(ft, ned, eph, epv)
            now = ft

    def fuse_reading(self, t: float, sd_m: float) -> bool:
        """Fuse the autopilot's estimate at simulated time t (its latest LOCAL_POSITION_NED
        stamped up to t, `_sample_at`) as a measurement of position + bias
        (`GpsEstimator.observe_reading`). Returns whether there was one."""
        sample = self._sample_at(t)
        if sample is None or self.estimator.time_s is None:
            return False
        at = np.array([sample[1], sample[2]]) + self.local_origin_in_field()[:2]
        self.estimator.observe_reading(max(sample[0], self.estimator.time_s), at, sd_m)
        return True

    def drop_fixes_until(self, t: float) -> None:
        """Discard the fixes stamped up to simulated time t (unfused), those still on their
        way included."""
        self._dropped_until = max(self._dropped_until, t)
        with self._fix_lock:
            while self._fixes and self._fixes[0][0] <= t + 1e-6:
                self._fixes.popleft()

    def skip_fixes_until(self, t: float) -> None:
        """Never fuse the fixes stamped up to simulated time t: those queued now are discarded
        when fuse_until reaches them, not at once (drop_fixes_until discards them at once)."""
        self._dropped_until = max(self._dropped_until, t)

    def take_fixes(self, t_start: float, t_end: float) -> list[Fix]:
        """The received fixes stamped in [t_start, t_end], unfused, for the caller to fuse its
        own way; every fix stamped up to t_end leaves the queue."""
        with self._fix_lock:
            due = [f for f in self._fixes if t_start - 1e-6 <= f[0] <= t_end + 1e-6]
            while self._fixes and self._fixes[0][0] <= t_end + 1e-6:
                self._fixes.popleft()
        return due

    def _sample_at(self, t: float) -> LocalSample | None:
        """The autopilot's latest LOCAL_POSITION_NED stamped up to simulated time t, by stamp
        (a reordering radio delivers samples late), leaving out one stamped within half a
        sample period of t: whether it has arrived with the frame of t is a race (the vehicle
        may hold its clock at t for the companion before or after sending it), and taking it
        or the one before changed a flight's camera estimate by millimetres from run to run.
        The one before is waited for a little, as fuse_until waits for its fix."""
        t = t - LOCAL_PERIOD_S / 2
        try:
            self.link.wait_for(lambda: bool(self.local_history) and self.local_history[-1][0] > t - LOCAL_PERIOD_S,
                               INPUT_WAIT_S, "")
        except LinkError:
            self.input_waits_timed_out += 1  # lost on the link: the latest that came
        window = [x for x in list(self.local_history) if t - SETTLED_LOOKBACK_S <= x[0] <= t + 1e-6]
        return max(window, key=lambda x: x[0]) if window else None

    def settled_at(self, t: float, local_ne: np.ndarray) -> bool:
        """Settled on the setpoint at simulated time t, by the autopilot's latest telemetry
        stamped up to t (deterministic given the trajectory, unless the link lost it)."""
        sample = self._sample_at(t)
        if sample is None:
            return False
        _, n, e, vn, ve = sample
        near_m = max(self.arrive_m, SETTLED_M)
        return bool(np.hypot(n - local_ne[0], e - local_ne[1]) < near_m and np.hypot(vn, ve) < SETTLED_SPEED)

    def down_at(self, t: float) -> tuple[float, float] | None:
        """The autopilot's (down, v down) estimate at simulated time t: the sample stamped with
        the one `_sample_at` reads (the same stamp rule), None without one."""
        sample = self._sample_at(t)
        if sample is None:
            return None
        for ts, d, vd in reversed(self.down_history):
            if ts == sample[0]:
                return d, vd
        return None

    def height_settled_at(self, t: float, down: float) -> bool:
        """Settled at the commanded height `down` (local, m) at simulated time t, by the
        autopilot's latest telemetry stamped up to t (SETTLED_DOWN_M, SETTLED_VSPEED)."""
        d = self.down_at(t)
        return d is not None and abs(d[0] - down) < SETTLED_DOWN_M and abs(d[1]) < SETTLED_VSPEED

    def local_at(self, t: float) -> np.ndarray | None:
        """The autopilot's (north, east) estimate at simulated time t by its telemetry."""
        sample = self._sample_at(t)
        return None if sample is None else np.array([sample[1], sample[2]])

    def wait_sim_time(self, t: float, timeout: float) -> None:
        self.link.wait_for(lambda: self.sim_time_s >= t, timeout, f"simulated time {t:.1f} s")
