"""ArduPilot's JSON physics backend, answered by our motor-driven PyBullet body.

ArduCopter started with `--model JSON:127.0.0.1 -I N` sends a servo frame to UDP 9002+10*N for
every physics step it wants (libraries/SITL/SIM_JSON.cpp and examples/JSON/readme.md in the
ArduPilot tree): 40 bytes <HHI16H, magic 18458, frame_rate (Hz), frame_count, pwm[16] (us),
or 72 bytes with magic 29569 and pwm[32]. It then blocks until a JSON line comes back from the
address it sent to: timestamp (s), imu.gyro (rad/s, body FRD), imu.accel_body (m/s^2, body
FRD, specific force), position (m, NED from home), velocity (m/s, NED), and the attitude as a
quaternion (w, x, y, z) or euler angles. Lockstep: one servo frame in, the body stepped by
1 / frame_rate, one state line out; ArduPilot's clock advances by our timestamp's step.

The parser there is a strstr/sscanf one: keys must be followed directly by `":` and vectors
written `[a,b,c]`; the line must be framed by newlines on both sides (it parses the text
between the last two).
"""

from __future__ import annotations

import select
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from sim.mavlink.runner import BackgroundRunner
from sim.vehicle.motor_quad import MotorQuadrotor

MAGIC_16 = 18458
MAGIC_32 = 29569
_PKT_16 = struct.Struct("<HHI16H")
_PKT_32 = struct.Struct("<HHI32H")
DEFAULT_RATE_HZ = 400
#: pwm above this on any motor: the motors spin, ArduPilot has armed (MOT_SPIN_ARM 0.1 -> 1100)
ARMED_PWM = 1050


def json_port(instance: int) -> int:
    """The UDP port ArduPilot's JSON backend sends servo frames to for `-I instance`."""
    return 9002 + 10 * instance


@dataclass(frozen=True)
class ServoFrame:
    frame_rate: int  # Hz: the step ArduPilot asks for is 1 / frame_rate
    frame_count: int
    pwm: tuple[int, ...]  # us, 16 or 32 channels

    @property
    def throttle(self) -> tuple[float, float, float, float]:
        """Motors 1..4 (SERVO1..4 = Motor1..4 on a quad) as 0..1 of MOT_PWM_MIN..MAX (1000..2000)."""
        return tuple(min(max((self.pwm[i] - 1000) / 1000.0, 0.0), 1.0) for i in range(4))  # type: ignore[return-value]

    @property
    def spinning(self) -> bool:
        return max(self.pwm[:4]) > ARMED_PWM


def parse_servo(data: bytes) -> ServoFrame | None:
    """A servo frame, or None for anything else (wrong size or magic)."""
    if len(data) == _PKT_16.size:
        fields = _PKT_16.unpack(data)
        magic = MAGIC_16
    elif len(data) == _PKT_32.size:
        fields = _PKT_32.unpack(data)
        magic = MAGIC_32
    else:
        return None
    if fields[0] != magic:
        return None
    return ServoFrame(fields[1], fields[2], tuple(fields[3:]))


def pack_servo(frame: ServoFrame) -> bytes:
    """The bytes ArduPilot would send (for tests and tools)."""
    if len(frame.pwm) == 16:
        return _PKT_16.pack(MAGIC_16, frame.frame_rate, frame.frame_count, *frame.pwm)
    if len(frame.pwm) == 32:
        return _PKT_32.pack(MAGIC_32, frame.frame_rate, frame.frame_count, *frame.pwm)
    raise ValueError(f"a servo frame has 16 or 32 channels (got {len(frame.pwm)})")


def _v(xs) -> str:
    return "[" + ",".join(f"{float(x):.7g}" for x in xs) + "]"


def format_state(timestamp_s: float, gyro, accel_body, position_ned, velocity_ned, quaternion) -> bytes:
    """The JSON line ArduPilot reads, framed by newlines (SIM_JSON.cpp parses between two)."""
    px, py, pz = (float(x) for x in position_ned)
    return (f'\n{{"timestamp":{timestamp_s:.6f},"imu":{{"gyro":{_v(gyro)},"accel_body":{_v(accel_body)}}},'
            f'"position":[{px:.6f},{py:.6f},{pz:.6f}],"velocity":{_v(velocity_ned)},'
            f'"quaternion":{_v(quaternion)}}}\n').encode()


def body_state_line(body: MotorQuadrotor, t: float) -> bytes:
    s, imu = body.state, body.imu
    return format_state(t, imu.gyro, imu.accel, s.position_ned, s.velocity_ned, body.quaternion)


class ArduPilotJsonBridge(BackgroundRunner):
    """Serve one ArduCopter's physics on UDP `port` (json_port(instance)), on a thread or in the
    foreground. on_step(t) runs after each step (the world's truth, targets, camera clock).

    t is the simulated time we sent last, the timestamp ArduPilot's clock follows."""

    def __init__(self, body: MotorQuadrotor, port: int, host: str = "127.0.0.1",
                 on_step: Callable[[float], None] | None = None, lock: threading.Lock | None = None) -> None:
        """lock: held while the body steps (a camera rendering the same PyBullet world takes it
        too: PyBullet is not thread-safe)."""
        self.body = body
        self.lock = lock or threading.Lock()
        self.on_step = on_step
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.port = port
        self.t = 0.0
        self.frames = 0
        self.duplicates = 0
        self.restarts = 0
        self.armed = False  # motors spinning on the last frame
        self.first_frame_wall: float | None = None
        self._last_count: int | None = None
        self._last_reply: bytes | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def handle(self, data: bytes, addr) -> bytes | None:
        """One datagram in: the reply to send (None for one that is not a servo frame)."""
        frame = parse_servo(data)
        if frame is None:
            return None
        if frame.frame_count == self._last_count and self._last_reply is not None:
            self.duplicates += 1  # ArduPilot resends after a second without an answer
            return self._last_reply
        if self._last_count is not None and frame.frame_count < self._last_count:
            self.restarts += 1  # ArduPilot restarted: physics time runs on (it copes)
        self._last_count = frame.frame_count
        rate = frame.frame_rate if frame.frame_rate > 0 else DEFAULT_RATE_HZ
        self.armed = frame.spinning
        with self.lock:
            self.body.set_throttle(frame.throttle)
            self.body.step(1.0 / rate)
            self.t += 1.0 / rate
            self.frames += 1
            if self.on_step is not None:
                self.on_step(self.t)
            self._last_reply = body_state_line(self.body, self.t)
        return self._last_reply

    def serve_once(self, timeout: float = 0.1) -> bool:
        ready, _, _ = select.select([self.sock], [], [], timeout)
        if not ready:
            return False
        data, addr = self.sock.recvfrom(256)
        reply = self.handle(data, addr)
        if reply is not None:
            if self.first_frame_wall is None:
                self.first_frame_wall = time.monotonic()
            self.sock.sendto(reply, addr)
        return True

    def run(self, duration: float | None = None) -> None:
        while not self._stop.is_set() and (duration is None or self.t < duration):
            self.serve_once()

    def _thread_name(self) -> str:
        return f"ardupilot-json-{self.port}"

    def _close(self) -> None:
        self.sock.close()
