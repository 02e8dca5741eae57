"""Free UDP ports for test vehicles (a module of its own: `from conftest import ...` resolves to
whichever conftest.py pytest imported first when several test folders run together)."""

import socket

#: every port handed out in this process: the OS may hand a just-released port out again at
#: once, and a fleet of 16 asking for 64 then got one twice ("Address already in use")
_handed_out: set[int] = set()


def free_udp_port() -> int:
    """A UDP port the OS has just handed out, and this process has not, so parallel tests and
    vehicles never meet."""
    while True:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port not in _handed_out:
            _handed_out.add(port)
            return port
