"""The camera as a MAVLink camera component (component 100), over real UDP loopback: on the SITL
vehicle's own link (as behind a MAVLink router) and standalone on its own socket; the PX4
autopilot beside it serves no frames."""

from __future__ import annotations

import time

import numpy as np
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as M
from udp_ports import free_udp_port

from autopilot_bridge.camera import FrameAssembler, decode_png_stamped
from sim.mavlink import CameraComponent, CameraInfo, UdpLink

CAM = M.MAV_COMP_ID_CAMERA


class Client:
    """A plain pymavlink peer (nothing of ours) that talks to any component."""

    def __init__(self, port: int) -> None:
        self.c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=250, source_component=190)
        # MAVLink 2's common dialect (the camera protocol's messages), whatever mavutil loaded
        self.c.mav = M.MAVLink(self.c, srcSystem=250, srcComponent=190)
        self.c.mav.robust_parsing = True
        self.c.WIRE_PROTOCOL_VERSION = "2.0"

    def recv(self, kinds, timeout: float = 5.0, cond=None):
        kinds = [kinds] if isinstance(kinds, str) else kinds
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.c.recv_match(type=kinds, blocking=True, timeout=0.2)
            if m is not None and (cond is None or cond(m)):
                return m
        return None

    def command(self, sysid: int, comp: int, cmd: int, *params: float, timeout: float = 3.0):
        p = list(params) + [0.0] * (7 - len(params))
        self.c.mav.command_long_send(sysid, comp, cmd, 0, *p)
        return self.recv("COMMAND_ACK", timeout, lambda a: a.command == cmd)

    def acks(self, cmd: int, seconds: float) -> list:
        """Every ACK of `cmd` within `seconds`: who answered."""
        out, end = [], time.monotonic() + seconds
        while time.monotonic() < end:
            m = self.c.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
            if m is not None and m.command == cmd:
                out.append(m)
        return out

    def frame(self, timeout: float = 5.0, comp: int = CAM):
        """The next whole frame from component `comp`: (pixels, stamp, PNG bytes' size)."""
        asm, end = FrameAssembler(), time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.c.recv_match(type=["DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA"], blocking=True, timeout=0.2)
            if m is None:
                continue
            assert m.get_srcComponent() == comp, f"a frame packet from component {m.get_srcComponent()}"
            size = asm.meta[0] if asm.meta else m.size if m.get_type() == "DATA_TRANSMISSION_HANDSHAKE" else None
            out = asm.feed(m)
            if out is not None:
                return out, asm.last_time_s, size
        return None, None, None

    def close(self) -> None:
        self.c.close()


def test_camera_component_heartbeats_describes_itself_and_serves_frames(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", camera=True, gcs_link=False, speedup=8.0,
                        camera_video_uri="udp://127.0.0.1:5600")
    c = Client(sitl.cfg.api_ports[1])
    try:
        hb = c.recv("HEARTBEAT", 5, lambda m: m.get_srcComponent() == CAM)
        assert hb is not None and hb.get_srcSystem() == sitl.cfg.sysid
        assert (hb.type, hb.autopilot) == (M.MAV_TYPE_CAMERA, M.MAV_AUTOPILOT_INVALID)
        ack = c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_CAMERA_INFORMATION)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED and ack.get_srcComponent() == CAM
        info = c.recv("CAMERA_INFORMATION", 3)
        assert info is not None and info.get_srcComponent() == CAM
        assert bytes(info.vendor_name).rstrip(b"\0") == b"uavsearch"
        assert bytes(info.model_name).rstrip(b"\0") == b"sim downward camera"
        assert (info.resolution_h, info.resolution_v) == (50, 50)
        assert info.flags & M.CAMERA_CAP_FLAGS_CAPTURE_IMAGE and info.flags & M.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
        ack = c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED
        vsi = c.recv("VIDEO_STREAM_INFORMATION", 3)
        assert vsi is not None and vsi.uri == "udp://127.0.0.1:5600" and vsi.type == M.VIDEO_STREAM_TYPE_RTPUDP
        for msg_id, kind in ((M.MAVLINK_MSG_ID_CAMERA_SETTINGS, "CAMERA_SETTINGS"),
                             (M.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS, "CAMERA_CAPTURE_STATUS")):
            ack = c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_REQUEST_MESSAGE, msg_id)
            assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED and c.recv(kind, 3) is not None

        # a timed capture: the picture of that simulated instant, from component 100, stamped
        at = sitl.t + 1.0
        ack = c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE, at)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED and ack.get_srcComponent() == CAM
        frame, stamp, size = c.frame()
        assert frame is not None and frame.shape == (50, 50, 3) and 60 < frame[..., 1].mean() < 200
        assert stamp is not None and at - 1e-6 <= stamp < at + 0.05
        # asked again (its frame lost on the way): the same stamped picture, byte for byte
        c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE, at)
        again, stamp2, size2 = c.frame()
        assert again is not None and np.array_equal(again, frame) and stamp2 == stamp and size2 == size
        assert sitl.camera is not None and sitl.camera.counters.images_captured == 1
    finally:
        c.close()


def test_the_px4_autopilot_denies_frames_and_leaves_broadcast_camera_requests_to_the_camera(sitl_factory) -> None:
    sitl = sitl_factory(physics="kinematic", camera=True, gcs_link=False, speedup=8.0)
    c = Client(sitl.cfg.api_ports[1])
    try:
        assert c.recv("HEARTBEAT", 5, lambda m: m.get_srcComponent() == 1) is not None
        ack = c.command(sitl.cfg.sysid, 1, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE)
        assert ack is not None and ack.get_srcComponent() == 1 and ack.result == M.MAV_RESULT_DENIED, "as real PX4"
        # to every component (0): the camera alone answers a camera request, the autopilot alone
        # the rest
        c.c.mav.command_long_send(sitl.cfg.sysid, 0, M.MAV_CMD_REQUEST_MESSAGE, 0,
                                  M.MAVLINK_MSG_ID_CAMERA_INFORMATION, 0, 0, 0, 0, 0, 0)
        acks = c.acks(M.MAV_CMD_REQUEST_MESSAGE, 1.0)
        assert [(a.get_srcComponent(), a.result) for a in acks] == [(CAM, M.MAV_RESULT_ACCEPTED)]
        c.c.mav.command_long_send(sitl.cfg.sysid, 0, M.MAV_CMD_REQUEST_MESSAGE, 0,
                                  M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
        acks = c.acks(M.MAV_CMD_REQUEST_MESSAGE, 1.0)
        assert [(a.get_srcComponent(), a.result) for a in acks] == [(1, M.MAV_RESULT_ACCEPTED)]
        # a command the camera does not know, addressed to it: UNSUPPORTED, from it
        ack = c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        assert ack is not None and ack.get_srcComponent() == CAM and ack.result == M.MAV_RESULT_UNSUPPORTED
        assert not sitl.model.state.armed
    finally:
        c.close()


def test_standalone_camera_component_on_its_own_socket() -> None:
    """The placement for a world process beside a real autopilot: the render function and the
    clock given, a UDP endpoint of its own, run on its own thread."""
    sim_t = [0.0]
    picture = np.zeros((24, 32, 3), dtype=np.uint8)
    picture[..., 1] = 120
    renders = []

    def render() -> np.ndarray:
        renders.append(sim_t[0])
        return picture

    local, remote = free_udp_port(), free_udp_port()
    c = Client(remote)
    cam = CameraComponent(render=render, clock=lambda: sim_t[0],
                          links=[UdpLink(local, remote, system_id=7, component_id=CAM)], system_id=7,
                          info=CameraInfo(width=32, height=24))
    cam.start()
    try:
        hb = c.recv("HEARTBEAT", 5)
        assert hb is not None and (hb.get_srcSystem(), hb.get_srcComponent(), hb.type) == (7, CAM, M.MAV_TYPE_CAMERA)
        ack = c.command(7, CAM, M.MAV_CMD_REQUEST_CAMERA_INFORMATION, 1)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED
        info = c.recv("CAMERA_INFORMATION", 3)
        assert info is not None and (info.resolution_h, info.resolution_v) == (32, 24)
        assert not info.flags & M.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
        ack = c.command(7, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION)
        assert ack is not None and ack.result == M.MAV_RESULT_UNSUPPORTED, "no video stream configured"
        # a capture asked for ahead waits for the world's clock
        ack = c.command(7, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_DATA_TRANSMISSION_HANDSHAKE, 2.5)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED
        time.sleep(0.2)
        assert not renders, "not before its time"
        sim_t[0] = 2.52
        frame, stamp, _ = c.frame()
        assert frame is not None and np.array_equal(frame, picture) and stamp == 2.52 and renders == [2.52]
        # IMAGE_START_CAPTURE of one picture: a fresh one at once, announced
        sim_t[0] = 3.0
        ack = c.command(7, CAM, M.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1)
        assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED
        frame, stamp, _ = c.frame()
        assert frame is not None and stamp == 3.0
        captured = c.recv("CAMERA_IMAGE_CAPTURED", 3)
        assert captured is not None and captured.capture_result == 1 and captured.image_index == 1
    finally:
        cam.close()
        c.close()
    assert cam.counters.frames_sent == 2


def test_stamps_are_the_png_text_chunk() -> None:
    """The stamp the companion reads is the one the camera writes (sim.mavlink.images)."""
    from sim.mavlink.images import encode_png

    frame, t = decode_png_stamped(encode_png(np.zeros((4, 4, 3), dtype=np.uint8), 12.25))
    assert frame.shape == (4, 4, 3) and t == 12.25


def test_the_camera_signs_on_a_signed_link(sitl_factory) -> None:
    """Behind the vehicle's router the camera signs with the link's key (a stream of its own):
    a peer holding the key verifies its packets and its ACKs."""
    key = bytes(range(32))
    sitl = sitl_factory(physics="kinematic", camera=True, gcs_link=False, speedup=8.0, signing_key=key)
    c = Client(sitl.cfg.api_ports[1])
    c.c.setup_signing(key, sign_outgoing=True)
    try:
        hb = c.recv("HEARTBEAT", 5, lambda m: m.get_srcComponent() == CAM)
        assert hb is not None and hb.get_signed(), "signed, and the signature checked out"
        ack = c.command(sitl.cfg.sysid, CAM, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_CAMERA_INFORMATION)
        assert ack is not None and ack.get_signed() and ack.result == M.MAV_RESULT_ACCEPTED
        assert c.c.mav.signing.badsig_count == 0
    finally:
        c.close()
