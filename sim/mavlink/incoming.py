"""What the vehicle does with each message that arrives: commands, mission protocol,
parameters, setpoints, manual control, TIMESYNC. A mixin of MavlinkVehicle. (Image requests
are the camera component's: camera_component.py.) Commands, setpoints, SET_MODE, HEARTBEATs
and anything else not answered here go to the vehicle's dialect; PX4's setpoint handling (its
dialect's) stays here."""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from .commands import RELATIVE_FRAMES, Command
from .mission import MissionProtocol
from .params import param_replies

M = mavlink
#: SET_POSITION_TARGET_LOCAL_NED frames flown: positions absolute, or offsets from here
LOCAL_FRAMES = frozenset({M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_OFFSET_NED, M.MAV_FRAME_BODY_OFFSET_NED,
                          M.MAV_FRAME_BODY_FRD})


class Incoming:
    def handle(self, msg: mavlink.MAVLink_message) -> None:
        kind = msg.get_type()
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.sysid):
            return
        # addressed to another component of this system (a camera, a gimbal): not ours to answer
        if getattr(msg, "target_component", None) not in (None, 0, M.MAV_COMP_ID_AUTOPILOT1):
            return
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._on_command(msg)
        elif kind in MissionProtocol.HANDLES:
            self.missions.handle(msg)
        elif kind in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            replies, refused = param_replies(self.mav, self.params, msg)
            if refused:
                self.statustext(f"Param rejected: {refused}", M.MAV_SEVERITY_WARNING)
            for reply in replies:
                self.send(reply)
        elif kind in ("SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT"):
            self.dialect.on_setpoint(self, msg)
        elif kind == "TIMESYNC" and msg.tc1 == 0:  # a request: answer with our clock (simulated ns)
            self.send(self.mav.timesync_encode(max(int(self.t * 1e9), 1), msg.ts1))
        elif kind == "HEARTBEAT":
            self.dialect.heard_heartbeat(self, msg)
        elif kind == "MANUAL_CONTROL":
            self._on_manual_control(msg)
            self.dialect.on_message(self, msg)
        elif kind == "SET_MODE":  # deprecated: obeyed like DO_SET_MODE, without an ACK
            self.dialect.on_set_mode(self, msg)
        else:
            self.dialect.on_message(self, msg)

    def _on_manual_control(self, msg: mavlink.MAVLink_message) -> None:
        """Sticks as QGroundControl's joystick sends them: x forward, y right, r yaw in
        [-1000, 1000], z throttle in [0, 1000] with 500 centred."""
        if msg.target not in (0, self.sysid):
            return
        sticks = np.array([msg.x, msg.y, msg.z - 500.0, msg.r], dtype=float) / np.array([1000, 1000, 500, 1000])
        self._sticks = np.clip(sticks, -1.0, 1.0)
        self._manual_wall_t = self.clock()

    def _on_command(self, msg: mavlink.MAVLink_message) -> None:
        self.counters.commands += 1
        self.hold_for_companion = False  # the companion acts: time runs on
        cmd = Command.from_msg(msg)
        result, then = self.dialect.execute(self, cmd)
        if result != M.MAV_RESULT_ACCEPTED:
            self.counters.denied += 1
        self.send(self.mav.command_ack_encode(cmd.id, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))
        if then is not None:
            then()

    def _on_setpoint(self, msg: mavlink.MAVLink_message) -> None:
        """OFFBOARD setpoints: accepted (and timed) in any mode, flown only in OFFBOARD, as PX4;
        the latest one before OFFBOARD is flown the moment OFFBOARD is entered (`set_mode`), as
        PX4 does, not when the client's stream happens to send the next (that tied the first
        metres after the switch to wall-clock timing: one seed flew 86 or 90 moves)."""
        self._offboard_wall_t = self.clock()
        self._offboard_sim_t = self.t
        if self.mode != "OFFBOARD":
            self._last_setpoint = msg
            return
        self._fly_setpoint(msg)

    def _fly_setpoint(self, msg: mavlink.MAVLink_message) -> None:
        mask = msg.type_mask
        vel = np.array([msg.vx, msg.vy, msg.vz], dtype=float)
        yaw = None if mask & M.POSITION_TARGET_TYPEMASK_YAW_IGNORE or not math.isfinite(msg.yaw) else float(msg.yaw)
        if msg.get_type() == "SET_POSITION_TARGET_GLOBAL_INT":
            rel = msg.alt if msg.coordinate_frame in RELATIVE_FRAMES else msg.alt - self.home.alt_m
            ned = self.home.geodetic_to_ned(msg.lat_int * 1e-7, msg.lon_int * 1e-7, self.home.alt_m)
            pos = np.array([ned[0], ned[1], -rel])
        else:
            if msg.coordinate_frame not in LOCAL_FRAMES:
                self.statustext(f"Setpoint frame {msg.coordinate_frame} not supported", M.MAV_SEVERITY_WARNING)
                return
            pos = np.array([msg.x, msg.y, msg.z], dtype=float)
            if msg.coordinate_frame in (M.MAV_FRAME_BODY_OFFSET_NED, M.MAV_FRAME_BODY_FRD):
                c, s = math.cos(self.model.state.attitude_rpy[2]), math.sin(self.model.state.attitude_rpy[2])
                rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                pos, vel = rot @ pos, rot @ vel
            if msg.coordinate_frame != M.MAV_FRAME_LOCAL_NED:
                pos = pos + self.estimate()
        if not mask & M.POSITION_TARGET_TYPEMASK_X_IGNORE:
            if not self.fence().allows(pos):  # NaN is outside every fence
                self.counters.fence_rejections += 1
                self.statustext("Geofence: offboard setpoint rejected", M.MAV_SEVERITY_WARNING)
                return
            self._target = pos
            self._command_model(pos, yaw=yaw, speed=self.params["MPC_XY_VEL_MAX"])
        elif not mask & M.POSITION_TARGET_TYPEMASK_VX_IGNORE:
            if not np.all(np.isfinite(vel)):
                return
            self._velocity_control = True
            self.model.set_velocity_target(vel)
