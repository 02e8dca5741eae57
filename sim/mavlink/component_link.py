"""Another MAVLink component of the same vehicle on the vehicle's own UDP link, as behind a
MAVLink router (mavlink-router, MAVLink's own routing in PX4): the camera's packets leave
through the vehicle's socket to the vehicle's peers, framed with the camera's component id and
its own sequence numbers (MAVLink counts sequence per component), signed with the link's key
when the link signs. What arrives is read by the vehicle, which hands the camera what is its
(MavlinkVehicle.service), so a peer sees one address with two components, as on a drone whose
companion and camera share the flight controller's telemetry radio."""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

from . import wire
from .udp import UdpLink, signing_timestamp


class SharedLink:
    """Sends as component `component_id` of the link's system through `link`'s socket; polls
    nothing (the link's owner reads the socket and routes). Closing it leaves the link open."""

    owns_socket = False

    def __init__(self, link: UdpLink, component_id: int) -> None:
        if not 1 <= component_id <= 255:
            raise ValueError(f"component_id must be in 1..255 (got {component_id})")
        if component_id == link.mav.srcComponent:
            raise ValueError(f"component {component_id} is the link's own component: a shared link needs another")
        self.link = link
        self.mav = mavlink.MAVLink(None, srcSystem=link.mav.srcSystem, srcComponent=component_id)
        signing = link.mav.signing
        if signing.sign_outgoing:  # the same key, a stream (sysid, compid, link id) of its own
            self.mav.signing.secret_key = signing.secret_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = signing.link_id
            self.mav.signing.timestamp = signing_timestamp()

    def send(self, msg: mavlink.MAVLink_message) -> None:
        """One packet to every peer of the link (and into its tlog, as the link's own packets)."""
        mav = self.mav
        if mav.signing.sign_outgoing:
            mav.signing.timestamp = max(mav.signing.timestamp, signing_timestamp())
            buf = msg.pack(mav)
        else:
            buf = wire.frame(msg, wire.payload(msg), mav.seq, mav.srcSystem, mav.srcComponent)
        mav.seq = (mav.seq + 1) & 0xFF
        self.link.send_foreign(buf)

    def poll(self) -> list[mavlink.MAVLink_message]:
        return []  # the link's owner reads the socket

    def close(self) -> None:
        """The link belongs to the vehicle: left open."""
