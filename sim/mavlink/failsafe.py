"""Failsafes, named and numbered as PX4's (parameters in params.py, docs in docs/safety.md).

- Offboard loss: no setpoint for COM_OF_LOSS_T in OFFBOARD -> Hold; after COM_FAIL_ACT_T more
  without setpoints -> COM_OBL_RC_ACT (0 Position, 1 Altitude, 2 Manual, 3 Return, 4 Land,
  5 Hold). Position/Altitude/Manual need sticks: without MANUAL_CONTROL the vehicle returns.
- Data-link loss: no HEARTBEAT from any ground station or companion (a non-autopilot peer)
  for COM_DL_LOSS_T while flying -> NAV_DLL_ACT (0 off, 1 Hold, 2 Return, 3 Land). Only a link
  that existed can be lost: a vehicle nobody ever talked to flies on.
- Battery: BAT_LOW_THR warns; BAT_CRIT_THR -> COM_LOW_BAT_ACT (0 warn, 2 Land, 3 Return at
  critical and land at emergency); BAT_EMERGEN_THR lands for 2 and 3.
- GPS loss: no fix for GPS_LOSS_S while flying -> Land (no position, nothing else is safe).
- Failure injection (MAV_CMD_INJECT_FAILURE, with SYS_FAILURE_EN = 1, as PX4): gps off, battery
  off (reads empty), mavlink_signal off (the vehicle neither hears nor sends; the INJECT_FAILURE
  that restores it is still heard), each back with FAILURE_TYPE_OK.
Timers that wait on a remote peer run on the wall clock, as the offboard timer does.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

M = mavlink
GPS_LOSS_S = 1.0
#: MAV_CMD_INJECT_FAILURE units this vehicle can fail
INJECTABLE = {M.FAILURE_UNIT_SENSOR_GPS: "gps", M.FAILURE_UNIT_SYSTEM_BATTERY: "battery",
              M.FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL: "mavlink_signal"}
OBL_MODES = {0: "POSCTL", 1: "POSCTL", 2: "POSCTL", 3: "AUTO.RTL", 4: "AUTO.LAND", 5: "AUTO.LOITER"}
DLL_MODES = {1: "AUTO.LOITER", 2: "AUTO.RTL", 3: "AUTO.LAND"}


class Failsafes:
    """A mixin of MavlinkVehicle: `_check_failsafes()` runs every tick before the flying."""

    def _init_failsafes(self) -> None:
        self.failures: set[str] = set()  # injected: "gps", "battery", "mavlink_signal"
        self.failsafe_log: list[tuple[float, str]] = []  # (simulated time, what fired)
        self._gcs_heartbeat_wall: float | None = None  # last heartbeat from a non-autopilot peer
        self._dll_active = False
        self._obl_since: float | None = None  # wall time the offboard-loss hold began
        self._no_fix_since: float | None = None
        self._bat_level = 0  # 0 ok, 1 low, 2 critical, 3 emergency (each acted on once)

    def heard_heartbeat(self, msg: mavlink.MAVLink_message) -> None:
        if msg.autopilot == M.MAV_AUTOPILOT_INVALID or msg.type == M.MAV_TYPE_GCS:
            self._gcs_heartbeat_wall = self.clock()

    def _failsafe(self, what: str, mode: str, severity: int = M.MAV_SEVERITY_CRITICAL) -> None:
        self.failsafe_log.append((self.t, what))
        self.statustext(f"Failsafe: {what}", severity)
        if mode != self.mode:
            self.set_mode(mode)

    def _flying(self) -> bool:
        s = self.model.state
        return s.armed and not s.landed

    def _check_failsafes(self) -> None:
        if not self._flying():
            self._obl_since = None
            self._no_fix_since = None
            return
        self._check_gps()
        self._check_battery()
        self._check_datalink()
        self._check_offboard()

    def _check_offboard(self) -> None:
        if self.mode == "OFFBOARD":
            if not self.offboard_fresh():
                self._obl_since = self.clock()
                self._failsafe("offboard setpoints lost: holding", "AUTO.LOITER", M.MAV_SEVERITY_WARNING)
            return
        if self._obl_since is None or self.mode != "AUTO.LOITER":
            self._obl_since = None  # someone else changed the mode: the failsafe is over
            return
        if self.offboard_fresh():
            return  # setpoints are back: hold, and let the companion take OFFBOARD again
        if self.clock() - self._obl_since < self.params["COM_FAIL_ACT_T"]:
            return
        self._obl_since = None
        act = int(self.params["COM_OBL_RC_ACT"])
        mode = OBL_MODES.get(act, "AUTO.RTL")
        if mode == "POSCTL" and not self.manual_fresh():
            mode = "AUTO.RTL"  # no sticks to fly position mode with
        self._failsafe(f"offboard lost, COM_OBL_RC_ACT={act}: {mode}", mode)

    def _check_datalink(self) -> None:
        last = self._gcs_heartbeat_wall
        if last is None:
            return
        lost = self.clock() - last > self.params["COM_DL_LOSS_T"]
        if not lost:
            if self._dll_active:
                self._dll_active = False
                self.statustext("Data link regained", M.MAV_SEVERITY_INFO)
            return
        if self._dll_active:
            return
        self._dll_active = True
        act = int(self.params["NAV_DLL_ACT"])
        if act in DLL_MODES:
            self._failsafe(f"data link lost, NAV_DLL_ACT={act}: {DLL_MODES[act]}", DLL_MODES[act])

    def _check_battery(self) -> None:
        r, act = self.battery.reading, int(self.params["COM_LOW_BAT_ACT"])
        level = 3 if r <= self.params["BAT_EMERGEN_THR"] else 2 if r <= self.params["BAT_CRIT_THR"] else (
            1 if r <= self.params["BAT_LOW_THR"] else 0)
        if level <= self._bat_level:
            return
        self._bat_level = level
        if level == 1:
            self._failsafe(f"battery low ({r:.0%})", self.mode, M.MAV_SEVERITY_WARNING)
        elif level == 2:
            mode = {2: "AUTO.LAND", 3: "AUTO.RTL"}.get(act, self.mode)
            self._failsafe(f"battery critical ({r:.0%}), COM_LOW_BAT_ACT={act}: {mode}", mode)
        elif act in (2, 3):
            self._failsafe(f"battery emergency ({r:.0%}): landing", "AUTO.LAND", M.MAV_SEVERITY_EMERGENCY)
        else:
            self._failsafe(f"battery emergency ({r:.0%})", self.mode, M.MAV_SEVERITY_EMERGENCY)

    def _check_gps(self) -> None:
        if self.fix is not None:
            self._no_fix_since = None
            return
        now = self.clock()
        if self._no_fix_since is None:
            self._no_fix_since = now
        elif now - self._no_fix_since > GPS_LOSS_S and self.mode != "AUTO.LAND":
            self._failsafe("GPS lost: landing", "AUTO.LAND")

    def inject_failure(self, unit: int, kind: int) -> int | tuple[int, object]:
        """MAV_CMD_INJECT_FAILURE -> MAV_RESULT, and the change to make after the ACK."""
        if self.params["SYS_FAILURE_EN"] < 0.5:
            self.statustext("Failure injection disabled (SYS_FAILURE_EN=0)", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_DENIED
        name = INJECTABLE.get(unit)
        if name is None or kind not in (M.FAILURE_TYPE_OK, M.FAILURE_TYPE_OFF):
            return M.MAV_RESULT_UNSUPPORTED
        self.statustext(f"Failure injected: {name} {'off' if kind else 'ok'}", M.MAV_SEVERITY_WARNING)

        def apply() -> None:
            if kind == M.FAILURE_TYPE_OFF:
                self.failures.add(name)
            else:
                self.failures.discard(name)
            self.battery.failed = "battery" in self.failures

        if kind == M.FAILURE_TYPE_OK:
            apply()  # restored before the ACK, so the ACK can go out
            return M.MAV_RESULT_ACCEPTED
        return M.MAV_RESULT_ACCEPTED, apply
