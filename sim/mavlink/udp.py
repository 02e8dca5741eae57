"""One MAVLink-over-UDP link as PX4 SITL opens them: bound to a local port, sending to a
default remote port and to every address that has talked to it.

Datagrams are parsed by pymavlink's codec; malformed bytes (bad CRC, truncated frames,
garbage) and messages failing the signature check are counted and dropped, never raised."""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

from . import wire


@dataclass
class LinkStats:
    received: int = 0
    sent: int = 0
    bad_data: int = 0
    rejected_unsigned: int = 0


log = logging.getLogger(__name__)
PEER_TTL_S = 10.0  # a peer silent this long gets no more telemetry
MAX_PEERS = 8  # peers streamed to besides the default remote
SIGNING_EPOCH_S = 1420070400  # 2015-01-01T00:00:00Z


def signing_timestamp(now_s: float | None = None) -> int:
    """MAVLink2 signing timestamp for a wall-clock time (10 us units since 2015)."""
    now = time.time() if now_s is None else now_s
    return int(max(now - SIGNING_EPOCH_S, 0.0) * 100_000)


class UdpLink:
    def __init__(
        self,
        local_port: int,
        remote_port: int,
        host: str = "127.0.0.1",
        system_id: int = 1,
        component_id: int = 1,
        signing_key: bytes | None = None,
        on_bytes: Callable[[bytes, bool], None] | None = None,
        log_outgoing: bool = True,
        bind: str = "0.0.0.0",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        # no SO_REUSEADDR: a second process on the same port must fail here, not silently
        # share (and take) this vehicle's commands
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((bind, local_port))
        except OSError as e:
            self.sock.close()
            raise OSError(e.errno, f"cannot bind UDP {bind}:{local_port} ({e.strerror}): is another vehicle "
                          "or program using this port?") from None
        self.sock.setblocking(False)
        self.clock = clock
        self.default_peer = (host, remote_port)
        self.peers: list[tuple[str, int]] = [self.default_peer]
        self._heard: dict[tuple[str, int], float] = {}  # peer -> when it last sent a good packet
        self.mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.stats = LinkStats()
        self._batch: list[bytes] | None = None  # packets held for one datagram (begin_batch)
        self.on_bytes = on_bytes  # (raw packet, outgoing) -> None, for the tlog
        self.log_outgoing = log_outgoing  # several links send the same stream: log it once
        if signing_key is not None:
            if len(signing_key) != 32:
                raise ValueError("a MAVLink2 signing key is 32 bytes")
            self.mav.signing.secret_key = signing_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = 0
            # the signing spec's clock: 10 us units since 2015-01-01; a peer drops a new stream
            # more than a minute older than its own clock, so it cannot start at zero
            self.mav.signing.timestamp = signing_timestamp()
            # RADIO_STATUS may come unsigned from radios (the MAVLink signing spec's exception)
            self.mav.signing.allow_unsigned_callback = lambda _m, msg_id: msg_id == mavlink.MAVLINK_MSG_ID_RADIO_STATUS

    def send(self, msg: mavlink.MAVLink_message, body: bytes | None = None) -> None:
        """Send one packet to every peer; `body`: the message's payload when the caller already
        has it (wire.payload, shared by the vehicle's links). Each packet takes the link's next
        sequence number, as MAVLink says (receivers count gaps as loss)."""
        mav = self.mav
        if mav.signing.sign_outgoing:  # the signing clock follows wall time, never frozen
            mav.signing.timestamp = max(mav.signing.timestamp, signing_timestamp())
            buf = msg.pack(mav)
        else:
            buf = wire.frame(msg, wire.payload(msg) if body is None else body, mav.seq, mav.srcSystem,
                             mav.srcComponent)
        mav.seq = (mav.seq + 1) & 0xFF
        self.stats.sent += 1
        if self.on_bytes and self.log_outgoing:
            self.on_bytes(bytes(buf), True)
        if self._batch is not None:
            self._batch.append(buf)
            return
        self._sendto_peers(buf)

    def send_packed(self, p: wire.Packed, framed: tuple[int, int, int, bytes] | None = None,
                    ) -> tuple[int, int, int, bytes]:
        """Send a Packed message (wire.ENCODER) as the link's next packet; unsigned links only.
        `framed`: (seq, sysid, compid, bytes) of the same message framed by another link of this
        vehicle, reused when this link's next number is the same (the vehicle sends every packet
        on every link, so its links count alike): one frame and CRC for both links."""
        seq, sysid, compid = numbers = self._numbers()
        buf = framed[3] if framed is not None and framed[:3] == numbers else wire.frame_packed(p, seq, sysid, compid)
        self._send_framed([buf])
        return seq, sysid, compid, buf

    def send_packets(self, packets: list[wire.Packed], framed: tuple[int, int, int, list[bytes]] | None = None,
                     ) -> tuple[int, int, int, list[bytes]]:
        """Send Packed messages as this link's next packets, in one datagram (unsigned links). `framed`:
        (first seq, sysid, compid, packets) of the same messages framed by another link of this
        vehicle, reused when this link's numbers are the same (see send_packed)."""
        seq, sysid, compid = numbers = self._numbers()
        bufs = framed[3] if framed is not None and framed[:3] == numbers else wire.frame_all(packets, seq, sysid, compid)
        self._send_framed(bufs)
        return seq, sysid, compid, bufs

    def _numbers(self) -> tuple[int, int, int]:
        """(next sequence number, system id, component id): what framing depends on."""
        mav = self.mav
        return mav.seq, mav.srcSystem, mav.srcComponent

    def _send_framed(self, bufs: list[bytes]) -> None:
        """Packets framed with this link's next numbers: count them, log them, and send them in
        one datagram (or hold them for the batch)."""
        if not bufs:
            return
        self.mav.seq = (self.mav.seq + len(bufs)) & 0xFF
        self.stats.sent += len(bufs)
        if self.on_bytes and self.log_outgoing:
            for buf in bufs:
                self.on_bytes(buf, True)
        if self._batch is not None:
            self._batch.extend(bufs)
        else:
            self._sendto_peers(bufs[0] if len(bufs) == 1 else b"".join(bufs))

    def send_foreign(self, buf: bytes) -> None:
        """A packet another component of this system framed with its own numbers (a camera
        sharing the socket, as behind a MAVLink router: component_link.SharedLink): counted,
        logged and sent (or batched) as this link's own, its sequence left alone."""
        self.stats.sent += 1
        if self.on_bytes and self.log_outgoing:
            self.on_bytes(bytes(buf), True)
        if self._batch is not None:
            self._batch.append(buf)
        else:
            self._sendto_peers(buf)

    def _sendto_peers(self, buf: bytes) -> None:
        for peer in self.peers:
            try:
                self.sock.sendto(buf, peer)
            except OSError:
                continue

    def begin_batch(self) -> None:
        """Hold what is sent until end_batch(), then send it as one datagram (several MAVLink
        packets back to back, as ArduPilot SITL sends them; every MAVLink parser reads them)."""
        self._batch = []

    def end_batch(self) -> None:
        batch, self._batch = self._batch, None
        if batch:
            self._sendto_peers(b"".join(batch))

    def poll(self) -> list[mavlink.MAVLink_message]:
        out = []
        while True:
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                break
            # UDP carries whole packets: a truncated one must not swallow the next datagram
            self.mav.buf, self.mav.buf_index = bytearray(), 0
            self.mav.expected_length, self.mav.have_prefix_error = mavlink.HEADER_LEN_V1 + 2, False
            rejected_before = self.mav.signing.reject_count + self.mav.signing.badsig_count
            bad_before = self.stats.bad_data
            try:
                msgs = self.mav.parse_buffer(data) or []
            except mavlink.MAVError:
                msgs = []
                self.stats.bad_data += 1
            rejected = self.mav.signing.reject_count + self.mav.signing.badsig_count - rejected_before
            self.stats.rejected_unsigned += rejected
            good = [m for m in msgs if m.get_type() != "BAD_DATA"]
            self.stats.bad_data += len(msgs) - len(good)
            leftover = len(self.mav.buf) - self.mav.buf_index
            if (not msgs and not rejected) or leftover > 0:
                self.stats.bad_data += 1 if data else 0
            if self.stats.bad_data > bad_before or rejected:
                self._log_drop(addr, data)
            if good:
                self._heard_from(addr)
                self.stats.received += len(good)
                if self.on_bytes:
                    self.on_bytes(data, False)
                out.extend(good)
        return out

    def _heard_from(self, addr: tuple[str, int]) -> None:
        """Telemetry goes to every peer heard within PEER_TTL_S (at most MAX_PEERS), plus the
        default remote: a thousand one-packet senders must not become a thousand streams."""
        now = self.clock()
        self._heard[addr] = now
        if len(self._heard) > MAX_PEERS or now - min(self._heard.values()) > PEER_TTL_S:
            fresh = sorted(((t, a) for a, t in self._heard.items() if now - t <= PEER_TTL_S), reverse=True)
            self._heard = {a: t for t, a in fresh[:MAX_PEERS]}
        self.peers = [self.default_peer] + [a for a in self._heard if a != self.default_peer]

    def _log_drop(self, addr: tuple[str, int], data: bytes) -> None:
        """Log dropped datagrams without flooding: the 1st, 10th, 100th, ... drop on this link."""
        total = self.stats.bad_data + self.stats.rejected_unsigned
        if str(total).rstrip("0") == "1":
            log.warning("port %d dropped a datagram from %s:%d (%d bytes, starts %s): %d malformed, %d unsigned "
                        "or badly signed so far", self.sock.getsockname()[1], addr[0], addr[1], len(data),
                        data[:8].hex(), self.stats.bad_data, self.stats.rejected_unsigned)

    def close(self) -> None:
        self.sock.close()
