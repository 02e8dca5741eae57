"""What the vehicle sends of its own accord: telemetry streams at their rates (paced in wall
time too), requested messages and STATUSTEXT. A mixin of MavlinkVehicle. (Camera frames come
from the camera component beside it, camera_component.py: an autopilot serves none.)"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink

from .telemetry import Snapshot

M = mavlink
STATUSTEXT_CHUNK = 50  # bytes of text in one STATUSTEXT
STATUSTEXT_KEEP = 200  # texts kept in the vehicle's counters (a history, not a leak)
#: telemetry streams run at most this many times their rate in wall-clock time
MAX_STREAM_SPEEDUP = 50.0


class Streams:
    def statustext(self, text: str, severity: int = M.MAV_SEVERITY_INFO) -> None:
        """STATUSTEXT as MAVLink 2 sends a long text: 50-byte chunks sharing a non-zero `id`,
        numbered by `chunk_seq`, the last one NUL-terminated (an empty chunk when the text fills
        its chunks exactly). A text of up to 50 bytes goes out whole with id 0, as PX4 does."""
        keep(self.counters.statustext, text, STATUSTEXT_KEEP)
        data = text.encode("utf-8", errors="replace")
        if len(data) <= STATUSTEXT_CHUNK:
            self.send(self.mav.statustext_encode(severity, data, 0, 0))
            return
        self._statustext_id = self._statustext_id % 0xFFFF + 1
        chunks = [data[i:i + STATUSTEXT_CHUNK] for i in range(0, len(data), STATUSTEXT_CHUNK)]
        if len(chunks[-1]) == STATUSTEXT_CHUNK:
            chunks.append(b"")
        for seq, chunk in enumerate(chunks[:256]):
            self.send(self.mav.statustext_encode(severity, chunk, self._statustext_id, seq))

    def _stream(self) -> None:
        if self.t + 1e-9 >= self._stream_next:  # most ticks nothing is due: one comparison
            if self.stream_sink is not None:  # a fleet's vehicle: the fleet builds and sends them
                due = self._due_streams()
                if due:
                    self.stream_sink.append((self, due))
            elif self.batch_streams:  # a fleet's vehicle: this tick's telemetry in one datagram per link
                for link in self.links:
                    link.begin_batch()
                try:
                    self._send_due_streams()
                finally:
                    for link in self.links:
                        link.end_batch()
            else:
                self._send_due_streams()

    def _send_due_streams(self) -> None:
        due = self._due_streams()
        if due:
            snap = self.snapshot()  # one snapshot for every message of this tick
            for msg_id in due:
                self.send_message(msg_id, snap)

    def _due_streams(self) -> list[int]:
        """The stream messages due now, in rate order; their next due times set. (Every vehicle
        runs this on 13 ticks a simulated second: locals, no min() calls.)"""
        t, now, soonest, due_ids = self.t, self.clock(), float("inf"), []
        te, next_due, next_wall = t + 1e-9, self._next_due, self._next_wall
        for msg_id, hz in self.rates.items():
            if hz <= 0:
                continue
            due = next_due.get(msg_id, 0.0)
            if te < due:
                if due < soonest:
                    soonest = due
                continue
            # on the lattice of its period in simulated time (k / hz), not a period after it was
            # last sent: the phase was set by when the companion asked for the stream (a wall-
            # clock race), so the sample a decision reads at its instant was stamped .92 in one
            # run and .86 in another on a loaded machine, and the flight differed (seed 2: 60 or
            # 24 moves)
            nxt = (math.floor(te * hz) + 1.0) / hz
            # never more than MAX_STREAM_SPEEDUP x the rate in wall time, so a simulation racing
            # ahead (speedup 0) cannot flood a client's receive buffer: a sample due too soon on
            # the wall clock is left out, not sent late (its stamp would be off the lattice)
            if now < next_wall.get(msg_id, 0.0):
                next_due[msg_id] = nxt
                if nxt < soonest:
                    soonest = nxt
                continue
            next_due[msg_id] = due = nxt
            if due < soonest:
                soonest = due
            next_wall[msg_id] = now + 1.0 / (hz * MAX_STREAM_SPEEDUP)
            due_ids.append(msg_id)
        self._stream_next = soonest
        return due_ids

    def snapshot(self) -> Snapshot:
        return Snapshot(self.t, self.model.state, self.estimate(), self.home, self.fix, self.mode, self.sysid,
                        fence_breached=self._fence_hold or self.fences.breached, battery_ok="battery" not in self.failures)

    def send_message(self, msg_id: int, snap: Snapshot | None = None) -> bool:
        """Send one message now (stream tick or REQUEST_MESSAGE); False if there is none to send.
        `snap`: this tick's snapshot, when the caller has one."""
        if msg_id == M.MAVLINK_MSG_ID_MISSION_CURRENT:
            self.send_mission_current()
            return True
        build = self.builders.get(msg_id)  # the dialect's (telemetry.BUILDERS for PX4)
        msg = build(self.enc, snap or self.snapshot()) if build is not None else None
        if msg is None:
            return False
        self.send(msg)
        return True


def keep(history: list, item: object, n: int) -> None:
    """Append to a bounded history: the latest n items."""
    history.append(item)
    if len(history) > n:
        del history[: len(history) - n]
