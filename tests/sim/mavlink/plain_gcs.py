"""A plain pymavlink ground station for the tests: nothing of ours, only mavutil."""

from __future__ import annotations

import time

from pymavlink import mavutil

M = mavutil.mavlink


class Gcs:
    def __init__(self, port: int, signing_key: bytes | None = None, sysid: int | None = None) -> None:
        self.c = mavutil.mavlink_connection(f"udpin:0.0.0.0:{port}", source_system=255, source_component=190)
        if signing_key is not None:
            self.c.setup_signing(signing_key, sign_outgoing=True)
        self.texts: list[str] = []  # every STATUSTEXT seen, whatever was being waited for
        if sysid is None:
            hb = self.c.wait_heartbeat(timeout=10)
            assert hb is not None, "no vehicle heartbeat"
            sysid = hb.get_srcSystem()
        else:  # learn the vehicle's address from any datagram, even one we cannot verify
            end = time.monotonic() + 5
            while not self.c.clients and time.monotonic() < end:
                self.c.recv_msg()
                time.sleep(0.01)
        self.sysid = sysid

    def recv(self, kind, timeout: float = 5.0, cond=None):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.c.recv_match(blocking=True, timeout=0.2)
            if m is None:
                continue
            if m.get_type() == "STATUSTEXT":
                self.texts.append(m.text)
            if m.get_type() == "HEARTBEAT" and m.autopilot == M.MAV_AUTOPILOT_INVALID:
                continue  # another component's (the camera's): the vehicle's state is the autopilot's
            kinds = [kind] if isinstance(kind, str) else kind
            if m.get_type() in kinds and (cond is None or cond(m)):
                return m
        return None

    def command(self, cmd: int, *params: float, timeout: float = 3.0, tries: int = 3, component: int = 1):
        """COMMAND_LONG to `component` (1: the autopilot), resent with confirmation+1 when no ACK
        comes, as QGC and MAVSDK do (UDP may drop a datagram on a loaded machine); the vehicle
        must answer each one, from the component asked."""
        p = list(params) + [0.0] * (7 - len(params))
        for confirmation in range(tries):
            self.c.mav.command_long_send(self.sysid, component, cmd, confirmation, *p)
            ack = self.recv("COMMAND_ACK", timeout / tries,
                            lambda a: a.command == cmd and a.get_srcComponent() == component)
            if ack is not None:
                return ack
        return None

    def close(self) -> None:
        self.c.close()
