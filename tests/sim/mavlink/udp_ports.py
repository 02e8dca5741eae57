"""Free UDP ports for test vehicles (a module of its own: `from conftest import ...` resolves to
whichever conftest.py pytest imported first when several test folders run together)."""

import socket


def free_udp_port() -> int:
    """A UDP port the OS has just handed out, so parallel tests and vehicles never meet."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
