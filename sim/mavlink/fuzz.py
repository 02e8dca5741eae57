"""A seeded MAVLink fuzzer for the vehicle's receiver, in the spirit of PX4's fuzzing of its
MAVLink receiver: three kinds of datagram, in proportions `mix`:

- random bytes (any length, sometimes starting with a MAVLink magic byte);
- well-formed frames (correct CRC, so they reach the handlers) of every message the vehicle
  handles, each field drawn from absurd values: NaN, +-inf, 0, -1, huge, type extremes, random;
- valid frames with bits flipped after the CRC was computed (the parser must drop them).

The CI test sends a few thousand; benchmarks/bench_fuzz.py sends a million and watches memory."""

from __future__ import annotations

import math
import socket
from collections.abc import Iterator

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from .commands import HANDLERS
from .mission import MissionProtocol

M = mavlink
#: the messages the vehicle reads (incoming.py)
TARGETS = sorted({"COMMAND_LONG", "COMMAND_INT", "PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET",
                  "SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT", "DATA_TRANSMISSION_HANDSHAKE",
                  "TIMESYNC", "HEARTBEAT", "MANUAL_CONTROL", "SET_MODE", *MissionProtocol.HANDLES})
FLOATS = (math.nan, math.inf, -math.inf, 0.0, -1.0, 1e38, -1e38, 1e-45, 3.5)
INT_RANGE = {"int8_t": (-128, 127), "uint8_t": (0, 255), "int16_t": (-32768, 32767), "uint16_t": (0, 65535),
             "int32_t": (-2**31, 2**31 - 1), "uint32_t": (0, 2**32 - 1), "int64_t": (-2**63, 2**63 - 1),
             "uint64_t": (0, 2**64 - 1), "char": (0, 255)}


class Fuzzer:
    def __init__(self, seed: int, sysid: int, mix: tuple[float, float, float] = (0.2, 0.6, 0.2)) -> None:
        self.rng = np.random.default_rng([seed, 0xF022])
        self.sysid = sysid
        self.mix = np.asarray(mix, float) / sum(mix)
        self.mav = mavlink.MAVLink(None, srcSystem=200, srcComponent=1)
        self.classes = [mavlink.mavlink_map[getattr(M, f"MAVLINK_MSG_ID_{n}")] for n in TARGETS]
        self.commands = sorted(HANDLERS)

    def _int(self, t: str, name: str) -> int:
        if name in ("target_system", "target"):
            return self.sysid if self.rng.random() < 0.8 else int(self.rng.integers(0, 256))
        if name == "target_component":
            return int(self.rng.choice([0, 1, 1, 1, int(self.rng.integers(0, 256))]))
        if name == "command":
            return int(self.rng.choice(self.commands)) if self.rng.random() < 0.8 else int(self.rng.integers(0, 65536))
        lo, hi = INT_RANGE.get(t, (0, 255))
        pick = self.rng.random()
        if pick < 0.3:
            return lo if self.rng.random() < 0.5 else hi
        if pick < 0.6:
            return int(self.rng.integers(0, 8))
        return int(self.rng.integers(max(lo, -2**62), min(hi, 2**62)))

    def _value(self, t: str, name: str, length: int):
        base = t.split("[")[0]
        if base == "char":
            n = int(self.rng.integers(0, length + 1)) if length else 1
            return bytes(self.rng.integers(0, 256, n, dtype=np.uint8))
        if length:
            return [self._value(base, name, 0) for _ in range(length)]
        if base in ("float", "double"):
            return float(self.rng.choice(FLOATS)) if self.rng.random() < 0.7 else float(self.rng.normal(0, 1e4))
        return self._int(base, name)

    def message(self) -> bytes:
        cls = self.classes[int(self.rng.integers(len(self.classes)))]
        args = []
        for name, t, length in zip(cls.fieldnames, cls.fieldtypes, cls.array_lengths, strict=False):
            args.append(self._value(t, name, length))
        try:
            return cls(*args).pack(self.mav)
        except Exception:  # noqa: BLE001 - a value struct cannot pack: draw again
            return self.message()

    def datagram(self) -> bytes:
        kind = int(self.rng.choice(3, p=self.mix))
        if kind == 0:
            n = int(self.rng.integers(0, 300))
            data = bytearray(self.rng.integers(0, 256, n, dtype=np.uint8).tobytes())
            if data and self.rng.random() < 0.5:
                data[0] = int(self.rng.choice([0xFD, 0xFE]))
            return bytes(data)
        data = self.message()
        if kind == 2:
            buf = bytearray(data)
            for _ in range(int(self.rng.integers(1, 4))):
                buf[int(self.rng.integers(len(buf)))] ^= 1 << int(self.rng.integers(8))
            return bytes(buf)
        return data

    def __iter__(self) -> Iterator[bytes]:
        while True:
            yield self.datagram()


def send_fuzz(port: int, n: int, seed: int, sysid: int, host: str = "127.0.0.1", per_sender: int = 0) -> int:
    """Send n fuzzed datagrams to host:port; with per_sender > 0, from a new source port every
    per_sender datagrams (many one-shot peers). Returns the count sent."""
    fz = Fuzzer(seed, sysid)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for i, data in zip(range(n), fz, strict=False):
            if per_sender and i and i % per_sender == 0:
                sock.close()
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                sock.sendto(data, (host, port))
            except OSError:
                pass
    finally:
        sock.close()
    return n
