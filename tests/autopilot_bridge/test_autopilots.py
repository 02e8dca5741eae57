"""The companion's dialects against each autopilot family, twice: against our own vehicle
speaking it (`sitl --dialect`, CI's stand-in) and against the real autopilot's own SITL (PX4
with SIH, ArduCopter with its own physics; skipped where PX4_SITL / ARDUPILOT_SITL are not
set). The same test bodies run on both, which is how the emulation is checked: the family is
recognised, the companion-loss failsafe is judged as the autopilot would act on it, the
take-off and a setpoint leg fly, and every way the companion can stop (the bring-down's rtl /
land / hold, and a companion that falls silent) ends landed and disarmed."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from real_sitl import arducopter, px4_sih

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.abort import bring_down
from autopilot_bridge.service.preflight import UnsafeFailsafe, ensure_failsafe, read_failsafe
from sim.mavlink import Sitl, SitlConfig

ALT = 3.5
pytestmark = pytest.mark.slow
BACKENDS = ("ours", "real")


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def vehicle(backend: str, family: str, instance: int) -> Iterator[VehicleLink]:
    """A link to a vehicle of this family: our SITL speaking its dialect (kinematic body, no
    camera, 10x), or the real autopilot's SITL (instance: PX4 0-9, ArduCopter any)."""
    if backend == "ours":
        sitl = Sitl(SitlConfig(dialect=family, physics="kinematic", camera=False, speedup=10.0, gcs_link=False,
                               api_local_port=_free_port(), api_remote_port=_free_port())).start()
        try:
            with VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}") as link:
                yield link
        finally:
            sitl.stop()
    elif family == "px4":
        with px4_sih(instance) as port, VehicleLink(f"udpin:0.0.0.0:{port}") as link:
            yield link
    else:
        with arducopter(instance, 25800 + instance) as port, VehicleLink(f"udpin:0.0.0.0:{port}") as link:
            yield link


def _take_off_and_leg(link: VehicleLink, set_failsafe: bool = False) -> None:
    """What the pilot does, without a camera: streams, failsafe, readiness, the family's
    take-off, then a 2 m leg north as streamed position setpoints, settled within 0.5 m."""
    link.wait_heartbeat(30)
    d = link.require_dialect()
    link.request_streams()
    ensure_failsafe(link, link.conn.mav.srcSystem, set_failsafe)
    link.wait_for(lambda: d.not_ready(link.telemetry) is None, 90, lambda: d.not_ready(link.telemetry) or "")
    if d.guided_before_arming:
        link.set_mode(d.guided_mode)
    link.arm(retry_s=10)
    link.takeoff(d.takeoff_altitude(link.telemetry.home["alt"], ALT))
    link.wait_for(lambda: link.telemetry.local.get("d", 0.0) < -(ALT - 0.5), 60, "the climb")
    n0, e0 = link.telemetry.local["n"], link.telemetry.local["e"]
    end = time.monotonic() + 30
    while time.monotonic() < end:
        link.set_position_ned(n0 + 2.0, e0, -ALT)
        if link.telemetry.mode != d.guided_mode:
            try:
                link.set_mode(d.guided_mode)
            except Exception:  # noqa: BLE001 - PX4 wants a second of setpoints first
                pass
        loc = link.telemetry.local
        if link.telemetry.mode == d.guided_mode and np.hypot(loc["n"] - n0 - 2.0, loc["e"] - e0) < 0.5 \
                and np.hypot(loc["vn"], loc["ve"]) < 0.3:
            return
        time.sleep(0.05)
    raise AssertionError(f"the leg did not settle: {link.telemetry.local}, mode {link.telemetry.mode}")


def _wait_disarmed(link: VehicleLink, timeout: float = 90.0) -> list[str]:
    """The modes the vehicle passed through until it disarmed (AssertionError if it did not)."""
    modes = [link.telemetry.mode]
    end = time.monotonic() + timeout
    while link.telemetry.armed and time.monotonic() < end:
        if link.telemetry.mode != modes[-1]:
            modes.append(link.telemetry.mode)
        time.sleep(0.05)
    assert not link.telemetry.armed, f"still armed after {timeout} s; modes {modes}"
    return modes


# -- PX4 --------------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_px4_is_recognised_and_its_default_failsafe_is_safe(backend: str) -> None:
    with vehicle(backend, "px4", 7) as link:
        link.wait_heartbeat(30)
        assert link.require_dialect().name == "px4"
        readings = {r.name: r for r in read_failsafe(link, 245)}
        assert set(readings) == {"COM_OF_LOSS_T", "COM_OBL_RC_ACT", "RTL_LAND_DELAY"}
        assert all(r.value is not None and r.ok for r in readings.values()), readings
        # an integer parameter set and read back bytewise: the unsafe Hold is refused by name
        assert link.set_param("COM_OBL_RC_ACT", 5) == 5
        with pytest.raises(UnsafeFailsafe, match=r"COM_OBL_RC_ACT = 5.*a safe value: 3"):
            ensure_failsafe(link, 245)
        assert ensure_failsafe(link, 245, set_safe=True) == ["--set-failsafe: COM_OBL_RC_ACT 5 -> 3"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_px4_comes_down_when_the_companion_falls_silent(backend: str) -> None:
    """A dead companion, as the vehicle sees it: no setpoints, no heartbeats."""
    with vehicle(backend, "px4", 8) as link:
        _take_off_and_leg(link)
        link.silence_heartbeats(True)
        modes = _wait_disarmed(link)
        assert "AUTO.RTL" in modes, modes


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("action", ["rtl", "land", "hold"])
def test_px4_bring_down(backend: str, action: str) -> None:
    with vehicle(backend, "px4", 9) as link:
        _take_off_and_leg(link)
        td = bring_down(link, action, timeout_s=90, hold_s=3, echo=lambda _s: None)
        assert td.disarmed, td


# -- ArduPilot --------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_ardupilot_refuses_its_default_failsafe_and_sets_it(backend: str) -> None:
    with vehicle(backend, "ardupilot", 11) as link:
        link.wait_heartbeat(60)
        assert link.require_dialect().name == "ardupilot"
        with pytest.raises(UnsafeFailsafe) as e:
            ensure_failsafe(link, 245)
        assert "FS_GCS_ENABLE = 0" in str(e.value) and "SYSID_MYGCS = 255" in str(e.value)
        changed = ensure_failsafe(link, 245, set_safe=True)
        assert any("FS_GCS_ENABLE 0 -> 1" in c for c in changed) and any("SYSID_MYGCS 255 -> 245" in c
                                                                         for c in changed), changed
        assert all(r.ok for r in read_failsafe(link, 245))


@pytest.mark.parametrize("backend", BACKENDS)
def test_ardupilot_comes_down_when_the_companion_falls_silent(backend: str) -> None:
    with vehicle(backend, "ardupilot", 12) as link:
        _take_off_and_leg(link, set_failsafe=True)
        link.silence_heartbeats(True)
        modes = _wait_disarmed(link, 120)
        assert "RTL" in modes, modes


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("action", ["rtl", "land", "hold"])
def test_ardupilot_bring_down(backend: str, action: str) -> None:
    with vehicle(backend, "ardupilot", 13) as link:
        _take_off_and_leg(link, set_failsafe=True)
        td = bring_down(link, action, timeout_s=120, hold_s=3, echo=lambda _s: None)
        assert td.disarmed, td
