"""Is a UDP port free? Both the SITL's sockets and pymavlink's `udpin` set SO_REUSEADDR, so on
Linux a second process binds the same port without complaint and the two silently share (or
steal) each other's datagrams. A probe bind without SO_REUSEADDR fails while either holds it."""

from __future__ import annotations

import errno
import socket


def udp_port_taken(port: int, host: str = "0.0.0.0") -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind((host, port))
        except OSError as e:
            if e.errno == errno.EADDRINUSE:
                return True
            raise
    return False


def udpin_port(address: str) -> int | None:
    """The local port of a pymavlink 'udpin:HOST:PORT' address (None for other kinds)."""
    kind, _, rest = address.partition(":")
    if kind not in ("udpin", "udp"):
        return None
    try:
        return int(rest.rsplit(":", 1)[1])
    except (IndexError, ValueError):
        return None
