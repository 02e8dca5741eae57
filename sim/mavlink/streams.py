"""What the vehicle sends of its own accord: telemetry streams at their rates (paced in wall
time too), requested messages, STATUSTEXT and camera frames. A mixin of MavlinkVehicle."""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

from .images import frame_messages
from .telemetry import BUILDERS, Snapshot

M = mavlink
#: telemetry streams run at most this many times their rate in wall-clock time
MAX_STREAM_SPEEDUP = 50.0


class Streams:
    def statustext(self, text: str, severity: int = M.MAV_SEVERITY_INFO) -> None:
        self.counters.statustext.append(text)
        self.send(self.mav.statustext_encode(severity, text[:50].encode()))

    def _stream(self) -> None:
        now = self.clock()
        for msg_id, hz in self.rates.items():
            if hz <= 0 or self.t + 1e-9 < self._next_due.get(msg_id, 0.0):
                continue
            # due in simulated time; but never more than MAX_STREAM_SPEEDUP x the rate in wall time,
            # so a simulation racing ahead (speedup 0) cannot flood a client's receive buffer
            if now < self._next_wall.get(msg_id, 0.0):
                continue
            self._next_due[msg_id] = self.t + 1.0 / hz
            self._next_wall[msg_id] = now + 1.0 / (hz * MAX_STREAM_SPEEDUP)
            self.send_message(msg_id)
        if self._pending_frames or (self.params["UAVS_CAM_RATE"] > 0 and self.t >= self._next_frame_t):
            self._send_frame()

    def snapshot(self) -> Snapshot:
        return Snapshot(self.t, self.model.state, self.estimate(), self.home, self.fix, self.mode, self.sysid)

    def send_message(self, msg_id: int) -> bool:
        """Send one message now (stream tick or REQUEST_MESSAGE); False if there is none to send."""
        if msg_id == M.MAVLINK_MSG_ID_MISSION_CURRENT:
            self.send_mission_current()
            return True
        if msg_id == M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE:
            self._pending_frames += 1  # a camera frame goes out on the next tick
            return True
        build = BUILDERS.get(msg_id)
        msg = build(self.mav, self.snapshot()) if build is not None else None
        if msg is None:
            return False
        self.send(msg)
        return True

    def _send_frame(self) -> None:
        if self.camera is None:
            self._pending_frames = 0
            return
        s = self.model.state
        frame = self.camera(s.position_ned, float(s.attitude_rpy[2]))
        for m in frame_messages(self.mav, frame):
            self.send(m)
        self.counters.frames_sent += 1
        self._pending_frames = max(0, self._pending_frames - 1)
        rate = self.params["UAVS_CAM_RATE"]
        self._next_frame_t = self.t + (1.0 / rate if rate > 0 else 0.0)
