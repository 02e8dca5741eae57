"""ArduCopter, as its source (master of 2024-05, fbb785859a) does it: looked up, not guessed.
The file and function each behaviour comes from is named where it is emulated; docs/sitl.md
lists what differs from the real autopilot.

- Modes (ArduCopter/mode.h Mode::Number): STABILIZE 0, ALT_HOLD 2, AUTO 3, GUIDED 4, LOITER 5,
  RTL 6, LAND 9, BRAKE 17; HEARTBEAT.custom_mode is the number; DO_SET_MODE takes it in
  param2 with MAV_MODE_FLAG_CUSTOM_MODE_ENABLED in param1, SET_MODE in custom_mode
  (GCS_MAVLINK::_set_mode_common). Boots in STABILIZE. Disarmed, any mode may be entered
  (Copter::set_mode: ignore_checks); armed, a mode needing a position needs the EKF's
  ("Mode change to GUIDED failed: requires position"). An unknown number: "No such mode N".
- Arming (AP_Arming_Copter): from the GCS in GUIDED, LOITER, STABILIZE, ALT_HOLD; a mode
  needing GPS arms only once the EKF has an absolute horizontal position (ekf_delay_s after
  boot, and a fix), else "Arm: Need Position Estimate" and COMMAND_ACK FAILED; "PreArm: ..."
  every 30 s while disarmed and failing (AP_Arming::update). "Arming motors" / "Disarming
  motors" (SITL builds). Armed on the ground without taking off, it disarms after
  DISARM_DELAY s (Copter::auto_disarm_check); LAND and RTL disarm on touchdown.
- GUIDED: NAV_TAKEOFF (param7 = metres above home) when armed and on the ground; setpoints
  heard in GUIDED only, flown only once airborne, each held until the next: no offboard-loss
  failsafe. Velocity setpoints stop after GUID_TIMEOUT s without one (ModeGuided
  get_timeout_ms). Type masks as GCS_MAVLINK_Copter::handle_message_set_position_target_*.
- The GCS failsafe (Copter::failsafe_gcs_check, failsafe_gcs_on_event): FS_GCS_ENABLE (0
  off, the default), FS_GCS_TIMEOUT (5 s), FS_OPTIONS (16: pilot-controlled modes carry on),
  fed only by HEARTBEAT (any MAV_TYPE), MANUAL_CONTROL and RC_CHANNELS_OVERRIDE from system
  SYSID_MYGCS (255), and only once that system has been heard.
- Streams: HEARTBEAT only, until asked (SRn_ rates default 0): SET_MESSAGE_INTERVAL per
  message, REQUEST_DATA_STREAM per stream group (GCS_MAVLINK::handle_request_data_stream).
- The polygon fence (fence_protocol.ArduPilotFenceProtocol, polyfence.py): enforced when
  FENCE_ENABLE is 1 and FENCE_TYPE has bit 2 (4, polygons; default 7), checked at 25 Hz
  (Copter::fence_check's scheduler rate) on the position estimate; a new breach in the air says
  "Fence Breached" and does FENCE_ACTION (Copter::fence_check: 0 report only, 1 RTL or Land (the
  default), 2 Land, 3 SmartRTL or RTL or Land, 4 Brake or Land, 5 SmartRTL or Land; SmartRTL is
  not emulated, its fallback is flown); breached on the ground, it disarms. GUIDED targets and
  repositions outside are refused (AC_Fence::check_destination_within_fence); arming outside is
  "Arm: vehicle outside fence" (AC_Fence::pre_arm_check). The cylinder (FENCE_RADIUS,
  FENCE_ALT_MAX) stays always on, whatever FENCE_ENABLE says, as before.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as apm
from pymavlink.dialects.v20 import common as mavlink

from sim.vehicle.geo import to_e7
from sim.vehicle.gps import GpsFix

from ..commands import RELATIVE_FRAMES, Command
from ..fence_protocol import ArduPilotFenceProtocol
from ..host import Host
from ..params import Param, ParamStore, default_params
from ..polyfence import ardupilot_breached
from . import Dialect
from .ardupilot_commands import execute
from .ardupilot_modes import (
    AUTOPILOT_MODES,
    MODES,
    NAMES,
    OTHER_MODES,
    REQUIRES_GPS,
    STICK_MODES,
)
from .ardupilot_telemetry import Builders

M = mavlink
#: FS_GCS_ENABLE -> FailsafeAction (defines.h FS_GCS_*, Copter::failsafe_gcs_on_event); an
#: invalid value falls back to RTL, as there
GCS_ACTIONS = {0: None, 1: "RTL", 2: "RTL", 3: "SMARTRTL", 4: "SMARTRTL_LAND", 5: "LAND", 6: "AUTO_DO_LAND_START",
               7: "BRAKE_LAND"}
FS_OPT_CONTINUE_IF_AUTO_GCS = 2  # FS_OPTIONS bits (Copter::FailsafeOption)
FS_OPT_CONTINUE_IF_LANDING = 8
FS_OPT_CONTINUE_IF_PILOT_CONTROL_GCS = 16
TIMESYNC_PERIOD_S = 10.0  # GCS_MAVLINK::update_send: a TIMESYNC request every 10 s
BRAKE_TIMEOUT_S = 2.5
ATTITUDE_FRACTION = 0.6  # of ekf_delay_s: when the attitude is ready (25 of 41 s in the real SITL)  # a failsafe's BRAKE turns LOITER after this (set_mode_brake_or_land_with_pause)
PREARM_DISPLAY_PERIOD_S = 30.0  # AP_Arming PREARM_DISPLAY_PERIOD
FENCE_CHECK_S = 0.04  # Copter::fence_check runs at 25 Hz
FENCE_TYPE_POLYGON = 4  # AC_FENCE_TYPE_POLYGON
#: FENCE_ACTION -> FailsafeAction of Copter::fence_check (SmartRTL's fallbacks)
FENCE_ACTIONS = {1: "RTL", 2: "LAND", 3: "RTL", 4: "BRAKE_LAND", 5: "LAND"}
#: SET_POSITION_TARGET type-mask groups as ArduCopter reads them: a group is ignored when any of
#: its bits is set (MAVLINK_SET_POS_TYPE_MASK_* in GCS_Mavlink.cpp)
POS_IGNORE, VEL_IGNORE, ACC_IGNORE = 0x007, 0x038, 0x1C0
FORCE_SET, YAW_IGNORE = 0x200, 0x400
LOCAL_FRAMES = frozenset({M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_OFFSET_NED, M.MAV_FRAME_BODY_NED,
                          M.MAV_FRAME_BODY_OFFSET_NED})
BODY_FRAMES = frozenset({M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_OFFSET_NED})
GLOBAL_FRAMES = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                           M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})
#: REQUEST_DATA_STREAM groups: the messages of each (ArduCopter/GCS_Mavlink.cpp STREAM_*_msgs)
#: that this vehicle builds; the others of the group are not emulated
STREAMS: dict[int, tuple[int, ...]] = {
    M.MAV_DATA_STREAM_RAW_SENSORS: (),
    M.MAV_DATA_STREAM_EXTENDED_STATUS: (M.MAVLINK_MSG_ID_SYS_STATUS, M.MAVLINK_MSG_ID_MISSION_CURRENT,
                                        M.MAVLINK_MSG_ID_GPS_RAW_INT),
    M.MAV_DATA_STREAM_RC_CHANNELS: (),
    M.MAV_DATA_STREAM_RAW_CONTROLLER: (),
    M.MAV_DATA_STREAM_POSITION: (M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED),
    M.MAV_DATA_STREAM_EXTRA1: (M.MAVLINK_MSG_ID_ATTITUDE,),
    M.MAV_DATA_STREAM_EXTRA2: (M.MAVLINK_MSG_ID_VFR_HUD,),
    M.MAV_DATA_STREAM_EXTRA3: (M.MAVLINK_MSG_ID_SYSTEM_TIME, M.MAVLINK_MSG_ID_BATTERY_STATUS,
                               apm.MAVLINK_MSG_ID_EKF_STATUS_REPORT),
}
INT8, INT16, INT32, REAL32 = (M.MAV_PARAM_TYPE_INT8, M.MAV_PARAM_TYPE_INT16, M.MAV_PARAM_TYPE_INT32,
                              M.MAV_PARAM_TYPE_REAL32)


def ardupilot_params(sysid: int) -> dict[str, Param]:
    """ArduCopter's parameters this vehicle acts on, with their defaults, units and wire types
    (ArduCopter/Parameters.cpp; Tools/autotest/default_params/copter.parm sets none of them),
    and our own UAVS_ / SIM_BAT_MIN_PCT ones (battery, camera, signing)."""
    px4 = default_params()
    return {
        "SYSID_THISMAV": Param(float(sysid), 1, 255, "MAVLink system id of this vehicle (set at start)", True,
                               wire_type=INT16),
        "SYSID_MYGCS": Param(255.0, 1, 255, "the ground station: only its HEARTBEAT, MANUAL_CONTROL and "
                             "RC_CHANNELS_OVERRIDE feed the GCS failsafe", wire_type=INT16),
        "FS_GCS_ENABLE": Param(0.0, 0, 7, "GCS failsafe: 0 off, 1 RTL, 2 RTL (removed: refuses arming), 3 SmartRTL or "
                               "RTL (here RTL), 4 SmartRTL or Land (here Land), 5 Land, 6 DO_LAND_START or RTL "
                               "(here RTL), 7 Brake or Land", values=tuple(range(8)), wire_type=INT8),
        "FS_GCS_TIMEOUT": Param(5.0, 2, 120, "GCS failsafe timeout (s)"),
        "FS_OPTIONS": Param(16.0, 0, 63, "failsafe options bitmask: 2 continue AUTO on GCS loss, 8 continue landing, "
                            "16 continue in pilot-controlled modes on GCS loss", wire_type=INT32),
        "DISARM_DELAY": Param(10.0, 0, 127, "disarm after this long (s) armed on the ground; 0 never", wire_type=INT8),
        "GUID_TIMEOUT": Param(3.0, 0.1, 5, "GUIDED: velocity setpoints stop after this long (s) without one"),
        "RTL_ALT": Param(1500.0, 200, 300000, "RTL altitude above home (cm)", wire_type=INT32),
        "RTL_LOIT_TIME": Param(5000.0, 0, 60000, "RTL: hover over home this long (ms) before landing", wire_type=INT32),
        "WPNAV_SPEED": Param(1000.0, 10, 2000, "horizontal speed to targets (cm/s)"),
        "WPNAV_RADIUS": Param(200.0, 5, 1000, "waypoint radius (cm): RTL's arrival over home"),
        "FENCE_RADIUS": Param(100.0, 1, 10000, "geofence: max horizontal distance from home (m)"),
        "FENCE_ALT_MAX": Param(30.0, 1, 1000, "geofence: max altitude above home (m)"),
        "FENCE_ENABLE": Param(0.0, 0, 1, "fence enabled: the polygon fence is enforced only when 1 (the cylinder "
                              "always is, here)", values=(0, 1), wire_type=INT8),
        "FENCE_TYPE": Param(7.0, 0, 15, "fence types bitmask: 1 max altitude, 2 circle about home, 4 "
                            "inclusion/exclusion polygons and circles, 8 min altitude", wire_type=INT8),
        "FENCE_ACTION": Param(1.0, 0, 5, "fence breach action: 0 report only, 1 RTL or Land, 2 Land, 3 SmartRTL or "
                              "RTL or Land (here RTL), 4 Brake or Land, 5 SmartRTL or Land (here Land)",
                              values=tuple(range(6)), wire_type=INT8),
        "FENCE_MARGIN": Param(2.0, 0, 100, "distance autopilots keep from the fence (m); not flown by this vehicle"),
        **{name: px4[name] for name in ("UAVS_BAT_ENDUR_S", "SIM_BAT_MIN_PCT", "UAVS_CAM_RATE", "UAVS_SIGNING")},
    }


#: the shared flying code's names for ArduCopter's parameters (params.Aliases)
ALIASES = {"MPC_XY_CRUISE": ("WPNAV_SPEED", 0.01), "MPC_XY_VEL_MAX": ("WPNAV_SPEED", 0.01),
           "NAV_ACC_RAD": ("WPNAV_RADIUS", 0.01), "RTL_RETURN_ALT": ("RTL_ALT", 0.01),
           "GF_MAX_HOR_DIST": ("FENCE_RADIUS", 1.0), "GF_MAX_VER_DIST": ("FENCE_ALT_MAX", 1.0)}
#: PX4 names the shared code reads on paths this dialect never takes (kept readable, unlisted)
HIDDEN = {"COM_OF_LOSS_T": 1.0, "COM_RC_LOSS_T": 0.5, "MIS_TAKEOFF_ALT": 3.5}


class ArduPilot(Dialect):
    name = "ardupilot"
    autopilot = M.MAV_AUTOPILOT_ARDUPILOTMEGA
    initial_mode = "STABILIZE"
    tracking_modes = frozenset({"GUIDED", "LOITER", "BRAKE", "RTL"})
    fleet_vectorised = False

    def __init__(self, ekf_delay_s: float = 3.0, sysid: int = 1, unix_start_s: float | None = None) -> None:
        """ekf_delay_s: simulated seconds from boot until the EKF has an absolute horizontal
        position; unix_start_s: the UTC time (s) at boot, for SYSTEM_TIME (None: now)."""
        if not (math.isfinite(ekf_delay_s) and ekf_delay_s >= 0):
            raise ValueError(f"ekf_delay_s must be >= 0 s (got {ekf_delay_s})")
        self.ekf_delay_s, self.sysid = float(ekf_delay_s), sysid
        self.unix0 = time.time() if unix_start_s is None else unix_start_s
        self.builders = Builders(self).table()
        self.rtc_set = False  # the GPS has set the clock (SYSTEM_TIME.time_unix_usec is 0 before)
        self.gcs_seen: tuple[float, float] | None = None  # (wall, simulated) time SYSID_MYGCS was last heard
        self.gcs_failsafe = False
        self.takeoff_z: float | None = None  # NED down of a user take-off under way
        self.rtl_phase, self.phase_t, self.rtl_alt = 0, 0.0, 0.0
        self.brake_until: float | None = None
        self.ground_since: float | None = None  # armed on the ground since (auto-disarm)
        self.velocity_heard = (-1e9, -1e9)  # (wall, simulated) time of the last velocity setpoint
        self.prearm_shown_t = 0.0
        self.was_armed = False
        self.ekf_announced = False  # "EKF3 IMU0 is using GPS", the origin and home sent
        self.timesync_t = 0.0

    # -- the dialect's tables ------------------------------------------------------------
    def default_rates(self) -> dict[int, float]:
        return {M.MAVLINK_MSG_ID_HEARTBEAT: 1.0}  # the rest only when asked

    def param_store(self, signing: bool, armed: Callable[[], bool]) -> ParamStore:
        # ArduPilot lets any parameter change while armed: nothing is locked
        return ParamStore(signing=signing, armed=armed, params=ardupilot_params(self.sysid), locked=(),
                          aliases=ALIASES, hidden=HIDDEN)

    def custom_mode(self, mode: str) -> int:
        return MODES[mode]

    def execute(self, v: Host, c: Command) -> tuple[int, Callable[[], object] | None]:
        return execute(self, v, c)

    # -- state the checks read -----------------------------------------------------------
    def position_ok(self, t: float, fix: GpsFix | None) -> bool:
        """The EKF has an absolute horizontal position (Copter::position_ok)."""
        return fix is not None and t >= self.ekf_delay_s

    def attitude_ok(self, t: float) -> bool:
        """The inertial sensors and the EKF's attitude have settled: a mode needing no position
        may arm (the real SITL armed in STABILIZE from ~25 s, its position came at ~41 s; before,
        "Arm: Accels inconsistent", "Arm: EKF attitude is bad", "Arm: Gyros inconsistent")."""
        return t >= ATTITUDE_FRACTION * self.ekf_delay_s

    def unix_usec(self, t: float) -> int:
        return int((self.unix0 + t) * 1e6) if self.rtc_set else 0

    def landing(self, v: Host) -> bool:
        return v.mode == "LAND" or (v.mode == "RTL" and self.rtl_phase >= 4)

    # -- modes ---------------------------------------------------------------------------
    def change_mode(self, v: Host, number: int) -> int:
        """A GCS asks for a mode by number (DO_SET_MODE, SET_MODE): the MAV_RESULT."""
        name = NAMES.get(number)
        if name is None:
            if number in OTHER_MODES:
                v.statustext(f"Mode change to {OTHER_MODES[number]} failed: not emulated", M.MAV_SEVERITY_WARNING)
            else:
                v.statustext(f"No such mode {number}", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_FAILED
        if name == v.mode:
            return M.MAV_RESULT_ACCEPTED
        s = v.model.state
        if s.armed:  # disarmed, every mode may be entered (Copter::set_mode ignore_checks)
            why = None
            if name in REQUIRES_GPS and not self.position_ok(v.t, v.fix):
                why = "requires position"
            elif name == "AUTO":
                why = "init failed"  # missions are not flown in AUTO here
            elif name in STICK_MODES and not s.landed:
                why = "not emulated in the air (no sticks)"
            if why is not None:
                v.statustext(f"Mode change to {name} failed: {why}", M.MAV_SEVERITY_WARNING)
                return M.MAV_RESULT_FAILED
        self.set_mode(v, name)
        return M.MAV_RESULT_ACCEPTED

    def set_mode(self, v: Host, mode: str) -> None:
        if mode == v.mode:
            return  # Copter::set_mode: already there, nothing re-initialised
        v.mode = mode
        self.takeoff_z, self.rtl_phase, self.brake_until = None, 0, None
        if mode == "LAND":
            v._target = None
            if v.model.state.armed:
                v.model.land()
        elif mode != "RTL":  # every other mode starts by holding where it is (GUIDED: zero velocity)
            v._hold_here()
        v.send_message(M.MAVLINK_MSG_ID_HEARTBEAT)  # as Copter::set_mode announces the change

    def on_set_mode(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        if msg.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            self.change_mode(v, int(msg.custom_mode))

    # -- what arrives --------------------------------------------------------------------
    def heard_heartbeat(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """GCS_MAVLINK::handle_heartbeat: only the sysid matters, not the MAV_TYPE."""
        if msg.get_srcSystem() == int(v.params["SYSID_MYGCS"]):
            self.gcs_seen = (v.clock(), v.t)

    def on_message(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        kind = msg.get_type()
        mine = msg.get_srcSystem() == int(v.params["SYSID_MYGCS"])
        if kind == "MANUAL_CONTROL" and mine and msg.target == v.sysid:  # handle_manual_control
            self.gcs_seen = (v.clock(), v.t)
        elif kind == "RC_CHANNELS_OVERRIDE" and mine:  # handle_rc_channels_override
            self.gcs_seen = (v.clock(), v.t)
        elif kind == "REQUEST_DATA_STREAM":
            self.request_data_stream(v, msg)

    def request_data_stream(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        if msg.start_stop not in (0, 1):
            return
        hz = float(msg.req_message_rate) if msg.start_stop == 1 else 0.0
        if msg.req_stream_id == M.MAV_DATA_STREAM_ALL:
            ids = [i for group in STREAMS.values() for i in group]
        else:
            ids = list(STREAMS.get(msg.req_stream_id, ()))
        for msg_id in ids:
            v.set_rate(msg_id, min(hz, 50.0))

    def on_setpoint(self, v: Host, msg: mavlink.MAVLink_message) -> None:
        """GCS_MAVLINK_Copter::handle_message_set_position_target_local_ned / _global_int:
        heard in GUIDED only; a frame it does not take stops the vehicle (mode_guided.init)."""
        if v.mode != "GUIDED":
            return
        s = v.model.state
        mask = int(msg.type_mask)
        pos_ignore, vel_ignore, acc_ignore = mask & POS_IGNORE, mask & VEL_IGNORE, mask & ACC_IGNORE
        if mask & FORCE_SET and not acc_ignore:
            return  # force setpoints are not taken
        yaw_c, yaw_s = math.cos(float(s.attitude_rpy[2])), math.sin(float(s.attitude_rpy[2]))
        vel = np.array([msg.vx, msg.vy, msg.vz], dtype=float)
        if msg.get_type() == "SET_POSITION_TARGET_GLOBAL_INT":
            if msg.coordinate_frame not in GLOBAL_FRAMES:
                self._stop(v)
                return
            ned = v.home.geodetic_to_ned(msg.lat_int * 1e-7, msg.lon_int * 1e-7, v.home.alt_m)
            rel = msg.alt if msg.coordinate_frame in RELATIVE_FRAMES else msg.alt - v.home.alt_m
            pos = np.array([ned[0], ned[1], -rel])
        else:
            if msg.coordinate_frame not in LOCAL_FRAMES:
                self._stop(v)
                return
            pos = np.array([msg.x, msg.y, msg.z], dtype=float)
            if msg.coordinate_frame in BODY_FRAMES:
                rot = np.array([[yaw_c, -yaw_s, 0.0], [yaw_s, yaw_c, 0.0], [0.0, 0.0, 1.0]])
                pos, vel = rot @ pos, rot @ vel
            if msg.coordinate_frame != M.MAV_FRAME_LOCAL_NED:
                pos = pos + v.estimate()
        if not (s.armed and (not s.landed or self.takeoff_z is not None)):
            return  # on the ground, GUIDED flies nothing until a NAV_TAKEOFF (is_disarmed_or_landed)
        yaw = None if mask & YAW_IGNORE or not math.isfinite(msg.yaw) else float(msg.yaw)
        if not pos_ignore:  # position, or position and velocity: the position is flown
            if not v.fence().allows(pos) or not self.polygon_allows(v, pos):  # NaN is outside every fence
                v.statustext("Geofence: guided setpoint rejected", M.MAV_SEVERITY_WARNING)
                return
            self.takeoff_z = None
            v._target = pos
            v._command_model(pos, yaw=yaw, speed=v.params["MPC_XY_VEL_MAX"])
        elif not vel_ignore:
            if not np.all(np.isfinite(vel)) or np.abs(vel).max() > 1e3:  # sane_vel_or_acc_vector
                self._stop(v)
                return
            self.takeoff_z = None
            v._velocity_control = True
            self.velocity_heard = (v.clock(), v.t)
            v.model.set_velocity_target(vel)
        else:  # acceleration only (not emulated) or nothing: stop, as an invalid input does
            self._stop(v)

    def _stop(self, v: Host) -> None:
        self.takeoff_z = None
        v._hold_here()

    # -- every tick ----------------------------------------------------------------------
    def step(self, v: Host) -> None:
        s = v.model.state
        if v.fix is not None:
            self.rtc_set = True
        if not self.ekf_announced and self.position_ok(v.t, v.fix):
            self._ekf_ready(v)
        if v.t - self.timesync_t > TIMESYNC_PERIOD_S:  # a request, as ArduPilot sends for its logs
            self.timesync_t = v.t
            v.send(v.mav.timesync_encode(0, max(int(v.t * 1e9), 1)))
        if self.was_armed and not s.armed:
            v.statustext("Disarming motors", M.MAV_SEVERITY_INFO)
        self.was_armed = s.armed
        self._gcs_failsafe_check(v)
        if v.fences.zones or v.fences.breached:
            self.check_fence(v)
        if not s.armed:
            self.ground_since = None
            if not self.position_ok(v.t, v.fix) and v.t - self.prearm_shown_t > PREARM_DISPLAY_PERIOD_S:
                self.prearm_shown_t = v.t
                v.statustext("PreArm: Need Position Estimate", M.MAV_SEVERITY_CRITICAL)
            return
        if s.landed:
            self._auto_disarm(v)
            return
        self.ground_since = None
        if self.takeoff_z is not None and abs(v.estimate()[2] - self.takeoff_z) < 0.3:
            self.takeoff_z = None  # up: GUIDED (LOITER) holds there
        if v.mode == "GUIDED" and v._velocity_control:
            wall, sim = self.velocity_heard
            limit = v.params["GUID_TIMEOUT"]
            if v.clock() - wall > limit and v.t - sim > limit:
                v._hold_here()  # velocity setpoints stale: stop
        elif v.mode == "BRAKE" and self.brake_until is not None and v.t >= self.brake_until:
            self.set_mode(v, "LOITER")
        elif v.mode == "RTL":
            self._fly_rtl(v)
        if v.mode not in ("RTL", "LAND") and not v.fence().allows(v.estimate()):
            self._failsafe(v, "fence breach: RTL", "RTL")

    def fence_protocol(self, v, clock) -> ArduPilotFenceProtocol:
        return ArduPilotFenceProtocol(v, clock)

    def polygon_fence_on(self, v: Host) -> bool:
        """AC_Fence: enabled, polygons selected, and some uploaded."""
        return bool(v.fences.zones) and int(v.params["FENCE_ENABLE"]) == 1 and bool(
            int(v.params["FENCE_TYPE"]) & FENCE_TYPE_POLYGON)

    def polygon_allows(self, v: Host, ned: np.ndarray) -> bool:
        """check_destination_within_fence's polygon part, for a target in local NED."""
        if not self.polygon_fence_on(v):
            return True
        if not np.all(np.isfinite(ned)):
            return False
        lat, lon, _ = v.home.ned_to_geodetic(ned)
        return not ardupilot_breached(v.fences.zones, to_e7(lat), to_e7(lon))

    def check_fence(self, v: Host) -> None:
        """AC_Fence::check_fence_polygon and Copter::fence_check (edge-triggered: a breach acts
        once, until the vehicle is back inside)."""
        f = v.fences
        if not self.polygon_fence_on(v):
            f.breached = False  # clear_breach(~_enabled_fences)
            return
        if v.t + 1e-9 < f.next_check_t:
            return
        f.next_check_t = v.t + FENCE_CHECK_S
        was, f.breached = f.breached, not self.polygon_allows(v, v.estimate())
        s = v.model.state
        if not f.breached or was or not s.armed:
            return
        if not s.landed:
            v.statustext("Fence Breached", M.MAV_SEVERITY_NOTICE)
        action = int(v.params["FENCE_ACTION"])
        if action == 0:
            return  # AC_FENCE_ACTION_REPORT_ONLY
        if s.landed:
            v.failsafe_log.append((v.t, "fence breach on the ground: disarm"))
            v.model.disarm(force=True)
            return
        mode = self._failsafe_mode(v, FENCE_ACTIONS.get(action, "RTL"))
        if mode is not None:
            self._failsafe(v, f"fence breach, FENCE_ACTION={action}: {mode}", mode)
            if mode == "BRAKE":
                self.brake_until = v.t + BRAKE_TIMEOUT_S

    def _ekf_ready(self, v: Host) -> None:
        """The EKF takes GPS (AP_NavEKF3_Control: "EKF3 IMU%u is using GPS", one per IMU lane)
        and sets its origin and home, each sent once unasked (as the real one was seen to)."""
        self.ekf_announced = True
        for lane in (0, 1):
            v.statustext(f"EKF3 IMU{lane} is using GPS", M.MAV_SEVERITY_INFO)
        v.send_message(M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)
        v.send_message(M.MAVLINK_MSG_ID_HOME_POSITION)

    def _auto_disarm(self, v: Host) -> None:
        """Copter::auto_disarm_check: armed on the ground, no take-off under way."""
        delay = v.params["DISARM_DELAY"]
        if self.takeoff_z is not None or delay <= 0 or self.landing(v):
            self.ground_since = None
            return
        if self.ground_since is None:
            self.ground_since = v.t
        elif v.t - self.ground_since >= delay:
            self.ground_since = None
            v.model.disarm()

    def _fly_rtl(self, v: Host) -> None:
        """ModeRTL: climb to RTL_ALT (if lower), fly home, hover RTL_LOIT_TIME, land, disarm."""
        p = v.estimate()
        if self.rtl_phase == 0:
            self.rtl_alt = min(max(-p[2], v.params["RTL_RETURN_ALT"]), v.params["GF_MAX_VER_DIST"] - 1.0)
            v._target = np.array([p[0], p[1], -self.rtl_alt])
            v._command_model(v._target, speed=v.params["MPC_XY_CRUISE"])
            self.rtl_phase = 1
        elif self.rtl_phase == 1 and abs(p[2] + self.rtl_alt) < 0.3:
            v._target = np.array([0.0, 0.0, -self.rtl_alt])
            v._command_model(v._target, speed=v.params["MPC_XY_CRUISE"])
            self.rtl_phase = 2
        elif self.rtl_phase == 2 and math.hypot(p[0], p[1]) < max(v.params["NAV_ACC_RAD"], 0.3):
            self.rtl_phase, self.phase_t = 3, v.t
        elif (self.rtl_phase == 3 and v.t - self.phase_t >= v.params["RTL_LOIT_TIME"] / 1000.0
              and math.hypot(p[0], p[1]) < 0.3):  # over home: the real one descends on it, position-held
            v._target = None
            v.model.land()
            self.rtl_phase = 4

    # -- the GCS failsafe ----------------------------------------------------------------
    def _gcs_failsafe_check(self, v: Host) -> None:
        """Lost when SYSID_MYGCS has been silent FS_GCS_TIMEOUT s of wall-clock time and of
        simulated time too (the real one counts simulated time alone: docs/sitl.md)."""
        enable = int(v.params["FS_GCS_ENABLE"])
        if enable == 0 or self.gcs_seen is None:
            return
        limit = v.params["FS_GCS_TIMEOUT"]
        lost = v.clock() - self.gcs_seen[0] > limit and v.t - self.gcs_seen[1] > limit
        if not lost and self.gcs_failsafe:
            self.gcs_failsafe = False
            v.statustext("GCS Failsafe Cleared", M.MAV_SEVERITY_WARNING)
        elif lost and not self.gcs_failsafe:
            self.gcs_failsafe = True
            self._gcs_failsafe_on(v, enable)

    def _gcs_failsafe_on(self, v: Host, enable: int) -> None:
        """Copter::failsafe_gcs_on_event, with its exceptions in its order."""
        action = GCS_ACTIONS.get(enable, "RTL")
        opts, s = int(v.params["FS_OPTIONS"]), v.model.state
        said = None
        if not s.armed:
            action = None
        elif s.landed:
            v.model.disarm()
            action, said = None, "Disarming"
        elif self.landing(v) and opts & FS_OPT_CONTINUE_IF_LANDING:
            action, said = "LAND", "Continuing Landing"
        elif v.mode == "AUTO" and opts & FS_OPT_CONTINUE_IF_AUTO_GCS:
            action, said = None, "Continuing Auto Mode"
        elif opts & FS_OPT_CONTINUE_IF_PILOT_CONTROL_GCS and v.mode not in AUTOPILOT_MODES:
            action, said = None, "Continuing Pilot Control"
        v.statustext("GCS Failsafe" if said is None else f"GCS Failsafe - {said}", M.MAV_SEVERITY_WARNING)
        mode = self._failsafe_mode(v, action)
        v.failsafe_log.append((v.t, f"GCS lost, FS_GCS_ENABLE={enable}: {mode or said or 'no action'}"))
        if mode is not None:
            self.set_mode(v, mode)
            if mode == "BRAKE":
                self.brake_until = v.t + BRAKE_TIMEOUT_S

    def _failsafe_mode(self, v: Host, action: str | None) -> str | None:
        """Copter::do_failsafe_action: the mode an action ends in (SmartRTL and DO_LAND_START
        are not emulated: their fallbacks, RTL or LAND, are flown)."""
        if action is None:
            return None
        if action in ("LAND", "SMARTRTL_LAND"):
            return "LAND"
        if action == "BRAKE_LAND":
            return "BRAKE" if self.position_ok(v.t, v.fix) else "LAND"
        return "RTL" if self.position_ok(v.t, v.fix) else "LAND"  # set_mode_RTL_or_land_with_pause

    def _failsafe(self, v: Host, what: str, mode: str) -> None:
        v.failsafe_log.append((v.t, what))
        v.statustext(f"Failsafe: {what}", M.MAV_SEVERITY_CRITICAL)
        self.set_mode(v, mode)
