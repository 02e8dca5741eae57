"""The endpoint's parts on their own: mode encoding, geofence, config validation, parameter
store, signing clock, tlog format."""

import math
import time

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from sim.mavlink import Geofence, SitlConfig, TlogWriter, px4_custom_mode, px4_mode_name
from sim.mavlink.params import ParamStore
from sim.mavlink.udp import signing_timestamp


@pytest.mark.parametrize(("name", "main", "sub"), [
    ("MANUAL", 1, 0), ("POSCTL", 3, 0), ("OFFBOARD", 6, 0), ("AUTO.LOITER", 4, 3), ("AUTO.MISSION", 4, 4),
    ("AUTO.RTL", 4, 5), ("AUTO.LAND", 4, 6), ("AUTO.TAKEOFF", 4, 2),
])
def test_px4_custom_mode_layout(name: str, main: int, sub: int) -> None:
    mode = px4_custom_mode(name)
    assert (mode >> 16) & 0xFF == main and mode >> 24 == sub and mode & 0xFFFF == 0  # px4_custom_mode.h
    assert px4_mode_name(main, sub) == name


def test_unknown_modes_are_none() -> None:
    assert px4_mode_name(99, 0) is None and px4_mode_name(4, 99) is None


def test_geofence_allows_and_clamps() -> None:
    f = Geofence(max_horizontal_m=10.0, max_altitude_m=5.0)
    assert f.allows(np.array([6.0, 8.0, -5.0])) and not f.allows(np.array([6.0, 8.1, 0.0]))
    assert not f.allows(np.array([0.0, 0.0, -5.1])) and not f.allows(np.array([math.nan, 0.0, 0.0]))
    inside = f.clamp(np.array([30.0, 40.0, -9.0]))
    assert np.hypot(*inside[:2]) == pytest.approx(9.0) and inside[2] == pytest.approx(-4.0)
    assert np.allclose(inside[:2] / np.linalg.norm(inside[:2]), [0.6, 0.8]), "straight back towards home"


@pytest.mark.parametrize("bad", [
    {"instance": 40}, {"speedup": -1.0}, {"physics": "xplane"}, {"system_id": 0}, {"gcs_remote_port": 70000},
    {"geofence": Geofence(-1.0, 10.0)},
])
def test_sitl_config_refuses_bad_values(bad: dict) -> None:
    with pytest.raises(ValueError):
        SitlConfig(**bad)


def test_sitl_config_px4_numbering_and_overrides() -> None:
    c = SitlConfig(instance=3, physics="kinematic")
    assert c.sysid == 4 and c.api_ports == (14583, 14543) and c.gcs_ports == (18573, 14550)
    c = SitlConfig(instance=3, physics="kinematic", system_id=42, gcs_remote_port=14553)
    assert c.sysid == 42 and c.gcs_ports == (18573, 14553)
    d = SitlConfig(signing_key=bytes(32), physics="kinematic").to_dict()
    assert d["signing"] is True and "signing_key" not in d


def test_param_store_ranges_and_read_only() -> None:
    p = ParamStore(signing=True)
    assert p.set("NAV_ACC_RAD", 1.5) == (True, "") and p["NAV_ACC_RAD"] == 1.5
    for name, value in (("NAV_ACC_RAD", -1.0), ("NAV_ACC_RAD", math.nan), ("NO_SUCH", 1.0), ("UAVS_SIGNING", 0.0)):
        ok, why = p.set(name, value)
        assert not ok and why
    assert p["NAV_ACC_RAD"] == 1.5 and p["UAVS_SIGNING"] == 1.0


def test_signing_timestamp_counts_10us_since_2015() -> None:
    assert signing_timestamp(1420070400.0) == 0
    assert signing_timestamp(1420070401.5) == 150_000
    assert abs(signing_timestamp() - (time.time() - 1420070400) * 1e5) < 1e5


def test_tlog_is_mavproxy_format(tmp_path) -> None:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    path = tmp_path / "x.tlog"
    w = TlogWriter(path, meta={"seed": 7})
    for i in range(3):
        w.write(mav.heartbeat_encode(2, 12, 0, i, 3).pack(mav))
    assert not path.exists(), "a log is renamed into place only when complete"
    w.close()
    log = mavutil.mavlink_connection(str(path))
    modes = []
    while (m := log.recv_match(type="HEARTBEAT")) is not None:
        modes.append(m.custom_mode)
        assert abs(m._timestamp - time.time()) < 60, "8-byte big-endian microseconds since the epoch"
    assert modes == [0, 1, 2]
    assert (tmp_path / "x.tlog.json").read_text().count('"seed": 7') == 1
