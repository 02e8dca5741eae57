"""The bridges' wire formats without the binaries: ArduPilot's servo frame and JSON state line
(libraries/SITL/examples/JSON/readme.md, read back the way SIM_JSON.cpp's strstr/sscanf parser
reads it), PX4's HIL_SENSOR / HIL_GPS packing, and both bridges served over real sockets by a
peer speaking the autopilot's side of the protocol."""

import math
import re
import socket
import struct
import time

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from sim.bridges.ardupilot_json import (
    MAGIC_16,
    MAGIC_32,
    ArduPilotJsonBridge,
    ServoFrame,
    format_state,
    pack_servo,
    parse_servo,
)
from sim.bridges.px4_hil import (
    FIELDS_ALL,
    EarthField,
    Px4HilBridge,
    hil_gps,
    hil_sensor,
    isa_pressure_hpa,
    px4_params,
)
from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsFix
from sim.vehicle.motor_quad import MotorQuadrotor


def _sim_json_parse(line: str) -> dict:
    """SIM_JSON.cpp's parse_sensors: per key, strstr the section, then the key after it, skip
    the key and two characters ('":'), then strtod or sscanf("[%f, %f, %f]")."""
    table = [("", "timestamp", 1), ("imu", "gyro", 3), ("imu", "accel_body", 3), ("", "position", 3),
             ("", "quaternion", 4), ("", "velocity", 3)]
    out = {}
    for section, key, n in table:
        p = line.find(section)
        assert p >= 0, section
        p += len(section) + 1
        p = line.find(key, p)
        assert p >= 0, key
        p += len(key) + 2
        if n == 1:
            out[key] = float(re.match(r"\s*([-+0-9.eE]+)", line[p:]).group(1))
        else:  # sscanf: the literal '[' first (no space skipped before it), ',' between
            m = re.match(r"\[" + r"\s*,".join([r"\s*([-+0-9.eE]+)"] * n) + r"\s*\]", line[p:])
            assert m is not None, (key, line[p:p + 40])
            out[key] = [float(x) for x in m.groups()]
    return out


def test_servo_frame_round_trip_and_rejects() -> None:
    pwm = tuple(range(1000, 1016))
    data = struct.pack("<HHI16H", MAGIC_16, 400, 7, *pwm)
    assert len(data) == 40 and pack_servo(parse_servo(data)) == data
    f = parse_servo(data)
    assert (f.frame_rate, f.frame_count, f.pwm) == (400, 7, pwm)
    assert f.throttle == pytest.approx((0.0, 0.001, 0.002, 0.003))
    f32 = ServoFrame(1200, 9, tuple([1500] * 32))
    assert len(pack_servo(f32)) == 72 and parse_servo(pack_servo(f32)) == f32
    assert parse_servo(struct.pack("<HHI32H", MAGIC_32, 1, 2, *[1000] * 32)).frame_rate == 1
    assert parse_servo(struct.pack("<HHI16H", 1234, 400, 7, *pwm)) is None  # wrong magic
    assert parse_servo(data[:-2]) is None
    assert ServoFrame(400, 1, (2500, 900) + (1000,) * 14).throttle == (1.0, 0.0, 0.0, 0.0)


def test_state_line_reads_back_through_ardupilots_parser() -> None:
    line = format_state(12.3456789, (0.1, -0.2, 0.3), (0.01, 0.02, -9.81), (1.5, -2.25, -3.5),
                        (0.4, 0.5, -0.6), (0.9, 0.1, -0.2, 0.3)).decode()
    assert line.startswith("\n{") and line.endswith("}\n") and line.count("\n") == 2  # framed by newlines
    d = _sim_json_parse(line)
    assert d["timestamp"] == pytest.approx(12.345679)
    assert d["gyro"] == pytest.approx([0.1, -0.2, 0.3]) and d["accel_body"] == pytest.approx([0.01, 0.02, -9.81])
    assert d["position"] == pytest.approx([1.5, -2.25, -3.5]) and d["velocity"] == pytest.approx([0.4, 0.5, -0.6])
    assert d["quaternion"] == pytest.approx([0.9, 0.1, -0.2, 0.3])
    import json

    assert set(json.loads(line)) == {"timestamp", "imu", "position", "velocity", "quaternion"}  # and it is JSON


def test_json_bridge_steps_once_per_frame_and_resends_duplicates() -> None:
    body = MotorQuadrotor()
    steps: list[float] = []
    bridge = ArduPilotJsonBridge(body, 0, on_step=steps.append)  # port 0: the OS picks one
    port = bridge.sock.getsockname()[1]
    bridge.start()
    ap = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    ap.settimeout(2.0)
    try:
        pwm = [int(1000 + 1000 * 0.9)] * 4 + [1000] * 12
        lines = []
        for count in range(400):  # one second at 400 Hz, nearly full throttle: it climbs
            ap.sendto(struct.pack("<HHI16H", MAGIC_16, 400, count, *pwm), ("127.0.0.1", port))
            lines.append(_sim_json_parse(ap.recv(4096).decode()))
        ap.sendto(struct.pack("<HHI16H", MAGIC_16, 400, 399, *pwm), ("127.0.0.1", port))  # a resend
        again = _sim_json_parse(ap.recv(4096).decode())
        assert again == lines[-1] and bridge.duplicates == 1 and bridge.frames == 400
        stamps = np.array([d["timestamp"] for d in lines])
        np.testing.assert_allclose(np.diff(stamps), 1 / 400, atol=2e-6)
        assert stamps[-1] == pytest.approx(1.0, abs=1e-5) and steps[-1] == pytest.approx(1.0)
        assert lines[-1]["position"][2] < -0.5 and lines[-1]["velocity"][2] < -1.0  # NED: up is negative
        assert bridge.armed and lines[-1]["accel_body"][2] < -9.81 - 1.0  # climbing hard: more than 1 g
    finally:
        ap.close()
        bridge.stop()
        body.close()


def test_hil_sensor_packs_what_px4_reads() -> None:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=51)
    m_ned = EarthField().ned()
    msg = hil_sensor(1_004_000, (0.1, 0.2, -9.8), (0.01, 0.02, 0.03), m_ned, 30.0)
    back = mavlink.MAVLink(None).parse_char(msg.pack(mav))
    assert back.get_type() == "HIL_SENSOR" and back.time_usec == 1_004_000
    assert (back.xacc, back.zacc, back.zgyro) == pytest.approx((0.1, -9.8, 0.03))
    assert back.fields_updated == FIELDS_ALL == 0x1BFF  # accel, gyro, mag, abs pressure, pressure alt, temperature
    assert back.abs_pressure == pytest.approx(1009.66, abs=0.05) and back.pressure_alt == pytest.approx(30.0)
    assert isa_pressure_hpa(0.0) == pytest.approx(1013.25) and back.temperature == pytest.approx(14.805)
    # the field at home: PX4's WMM tables at our default home
    assert math.hypot(back.xmag, back.ymag, back.zmag) == pytest.approx(0.4895, abs=1e-4)
    assert math.degrees(math.atan2(back.zmag, math.hypot(back.xmag, back.ymag))) == pytest.approx(66.23, abs=0.01)
    fix = GpsFix(1.0, 51.4545, -2.5879, 30.5, np.array([1.0, -1.0, 0.1]), 0.92, 1.4, 3, 12)
    g = mavlink.MAVLink(None).parse_char(hil_gps(2_000_000, fix).pack(mav))
    assert (g.lat, g.lon, g.alt, g.fix_type, g.satellites_visible) == (514545000, -25879000, 30500, 3, 12)
    assert (g.vn, g.ve, g.vd, g.vel, g.eph) == (100, -100, 10, 141, 92) and g.cog == 31500
    p = px4_params(EarthField())
    assert p["CA_ROTOR0_PX"] > 0 and p["CA_ROTOR0_PY"] > 0 and p["CA_ROTOR0_KM"] > 0  # front-right CCW
    assert p["CA_ROTOR3_PX"] < 0 and p["CA_ROTOR3_PY"] > 0 and p["CA_ROTOR3_KM"] < 0  # back-right CW
    assert p["EKF2_GPS_CHECK"] == 1567


def test_px4_bridge_lockstep_over_tcp() -> None:
    """A peer on PX4's side: connect, read HIL_SENSOR, answer HIL_ACTUATOR_CONTROLS per step.
    Its clock is the time_usec we send; armed and above hover, the body climbs."""
    body = MotorQuadrotor()
    home = HomePosition(51.4545, -2.5879, 30.0)
    bridge = Px4HilBridge(body, 0, home, seed=1, speedup=0, lockstep_timeout_s=2.0)
    port = bridge.server.getsockname()[1]
    bridge.start()
    px4 = socket.create_connection(("127.0.0.1", port), timeout=5)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    sensors, gps = [], []
    try:
        u = 0.9
        end = time.monotonic() + 20
        while len(sensors) < 250 and time.monotonic() < end:
            for msg in mav.parse_buffer(px4.recv(65536)) or []:
                if msg.get_type() == "HIL_SENSOR":
                    sensors.append(msg)
                    px4.sendall(mavlink.MAVLink_hil_actuator_controls_message(
                        msg.time_usec, [u] * 4 + [0.0] * 12, 128, 1).pack(mav))
                elif msg.get_type() == "HIL_GPS":
                    gps.append(msg)
        assert len(sensors) >= 250
        stamps = np.array([m.time_usec for m in sensors])
        assert stamps[0] == 1_004_000 or stamps[0] == 1_000_000
        assert np.all(np.diff(stamps) == 4000)  # 250 Hz, one step per answer
        assert 4 <= len(gps) <= 6 and gps[0].fix_type == 3  # 5 Hz
        assert bridge.armed and bridge.lockstep_timeouts == 0
        assert sensors[-1].zacc < -12 and sensors[0].zacc == pytest.approx(-9.81, abs=0.1)
        time.sleep(0.2)
        assert body.state.position_ned[2] < -0.3  # a second at 0.9: it rose
    finally:
        bridge._stop.set()
        px4.close()
        bridge.stop()
        body.close()
