"""The dialects' codecs and rules."""

from __future__ import annotations

import pytest

from autopilot_bridge.link.connection import mavlink
from autopilot_bridge.link.dialects import ArduPilot, by_name, for_autopilot
from autopilot_bridge.link.dialects.ardupilot import MODES
from autopilot_bridge.link.dialects.base import Dialect


def _rules(d: Dialect, sysid: int = 245) -> dict:
    return {r.name: r for r in d.failsafe_rules(sysid)}


def test_families_by_heartbeat_and_name() -> None:
    assert for_autopilot(mavlink.MAV_AUTOPILOT_PX4).name == "px4"
    assert for_autopilot(mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA).name == "ardupilot"
    assert for_autopilot(mavlink.MAV_AUTOPILOT_GENERIC) is None
    with pytest.raises(ValueError, match="unknown autopilot 'inav'"):
        by_name("inav")


def test_px4_modes_round_trip() -> None:
    px4 = by_name("px4")
    for name in ("OFFBOARD", "AUTO.LOITER", "AUTO.RTL", "AUTO.LAND", "POSCTL"):
        base, main, sub = px4.set_mode_params(name)
        assert base == mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        assert px4.decode_mode((int(sub) << 24) | (int(main) << 16)) == name
    with pytest.raises(ValueError, match="GUIDED"):
        px4.set_mode_params("GUIDED")


def test_ardupilot_modes_round_trip_and_roles() -> None:
    ap = by_name("ardupilot")
    for name, number in MODES.items():
        assert ap.set_mode_params(name)[1] == number
        assert ap.decode_mode(number) == name
    assert (ap.guided_mode, ap.land_mode, ap.rtl_mode, ap.hold_mode) == ("GUIDED", "LAND", "RTL", "BRAKE")
    assert ap.decode_mode(99) == "MODE99"
    assert ap.takeoff_altitude(30.0, 3.5) == 3.5 and by_name("px4").takeoff_altitude(30.0, 3.5) == 33.5
    with pytest.raises(ValueError, match="OFFBOARD"):
        ap.set_mode_params("OFFBOARD")


def test_px4_integer_parameters_travel_bytewise() -> None:
    px4, ap = by_name("px4"), by_name("ardupilot")
    wire = px4.param_encode(3, mavlink.MAV_PARAM_TYPE_INT32)
    assert wire != 3.0 and px4.param_value(wire, mavlink.MAV_PARAM_TYPE_INT32) == 3.0
    assert px4.param_value(1.5, mavlink.MAV_PARAM_TYPE_REAL32) == 1.5
    assert ap.param_encode(3, mavlink.MAV_PARAM_TYPE_INT8) == 3.0  # ArduPilot: the value, cast


def test_ardupilot_readiness_needs_the_ekf() -> None:
    class T:
        gps = {"fix_type": 3}
        home = {"lat": 0.0}
        ekf_flags = None

    ap = ArduPilot()
    assert "EKF_STATUS_REPORT" in ap.not_ready(T)
    T.ekf_flags = 0x0F | 128  # const-position mode: not yet
    assert "absolute horizontal position" in ap.not_ready(T)
    T.ekf_flags = 0x1F
    assert ap.not_ready(T) is None


def test_failsafe_rules_judge_as_the_autopilots_act() -> None:
    px4 = _rules(by_name("px4"))
    assert px4["COM_OBL_RC_ACT"].ok(3) and px4["COM_OBL_RC_ACT"].ok(0)
    assert not any(px4["COM_OBL_RC_ACT"].ok(v) for v in (5, 6, 7))  # hold, terminate, disarm
    assert not px4["COM_OF_LOSS_T"].ok(0) and px4["COM_OF_LOSS_T"].ok(1.0)
    assert not px4["RTL_LAND_DELAY"].ok(-1)
    ap = _rules(by_name("ardupilot"), 245)
    assert not ap["FS_GCS_ENABLE"].ok(0) and ap["FS_GCS_ENABLE"].ok(1) and ap["FS_GCS_ENABLE"].ok(5)
    assert not ap["SYSID_MYGCS"].ok(255) and ap["SYSID_MYGCS"].ok(245) and ap["SYSID_MYGCS"].safe == 245
    assert not ap["RTL_ALT_FINAL"].ok(200)
    for rules in (px4, ap):
        for r in rules.values():  # every suggested value is one the rule accepts
            assert r.ok(r.safe), r.name
