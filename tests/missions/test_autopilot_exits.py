"""Every way a search can stop mid-flight, on each autopilot, ends with the vehicle landed and
disarmed: Ctrl-C and SIGTERM (the companion brings it down), a companion killed -9 and a cut
link (the autopilot's own companion-loss failsafe does, as `--set-failsafe` set it up).

The processes are the operator's: `uavsearch sitl` (our vehicle speaking ArduPilot's dialect in
CI; the real ArduCopter / PX4 flying our world where ARDUPILOT_SITL / PX4_SITL are set),
`uavsearch run`, and a plain pymavlink ground station. A cut link is a proxy between the
companion and the autopilot that stops passing anything at all."""

from __future__ import annotations

import os
import signal
import socket
from dataclasses import dataclass
from pathlib import Path

import pytest
from flight_procs import GroundStation, Lines, stop_process, uavsearch, until

from sim.mavlink.faultproxy import FaultProxy

pytestmark = pytest.mark.slow
EXITS = ("SIGINT", "SIGTERM", "kill9", "cut")


@dataclass(frozen=True)
class Backend:
    name: str
    sitl_args: tuple[str, ...]
    env: str | None  # the binary's variable (None: our own vehicle)
    vehicle_listens: bool  # the autopilot's API link listens on 14580 + N (else: an ephemeral port)
    gcs_fixed: bool = False  # its GCS link sends to 14550 whatever the instance (PX4)


BACKENDS = {
    "ours-ardupilot": Backend("ours-ardupilot", ("--dialect", "ardupilot", "--speedup", "16", "--physics", "kinematic"),
                              None, True),
    "real-ardupilot": Backend("real-ardupilot", ("--autopilot", "ardupilot", "--speedup", "5"), "ARDUPILOT_SITL", False),
    "real-px4": Backend("real-px4", ("--autopilot", "px4", "--speedup", "5"), "PX4_SITL", True, gcs_fixed=True),
}
INSTANCE = {"ours-ardupilot": 6, "real-ardupilot": 7, "real-px4": 8}


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("how", EXITS)
@pytest.mark.parametrize("backend", list(BACKENDS))
def test_a_search_stopped_mid_flight_ends_landed_and_disarmed(tmp_path: Path, backend: str, how: str) -> None:
    b = BACKENDS[backend]
    if b.env is None and how in ("SIGINT", "SIGTERM"):
        pytest.skip("our vehicle's signal exits: tests/missions/test_flight_processes.py (PX4 dialect) and the "
                    "ArduPilot dialect's bring-down in tests/autopilot_bridge/test_autopilots.py (CI's 10 min)")
    if b.env is not None and not os.environ.get(b.env):
        pytest.skip(f"{b.env} is not set (a real autopilot SITL binary: see ../shared/peers/build_*.sh)")
    n = INSTANCE[backend]
    gcs = GroundStation(14550 if b.gcs_fixed else 14550 + n)
    field_file = tmp_path / "field.json"
    sitl = uavsearch("sitl", "--instance", str(n), "--gcs-port-per-instance", "--field-out", str(field_file),
                     "--width", "6", "--height", "6", "--targets", "3", "--seed", "5", *b.sitl_args)
    sitl_out = Lines(sitl)
    proxy = None
    run = None
    try:
        assert sitl_out.wait_for("uavsearch run --field", 60), sitl_out.text
        assert until(lambda: bool(gcs.seen.armed), 60), "the ground station hears the vehicle"
        connect = []
        if how == "cut":  # the companion reaches the autopilot through a radio that will fail
            client = _free_port()
            proxy = FaultProxy(14580 + n if b.vehicle_listens else 0, client, vehicle_side_port=14540 + n).start()
            connect = ["--connect", f"udpin:0.0.0.0:{client}"]
        run = uavsearch("run", "--field", str(field_file), *connect, "--policy", "lawnmower", "--set-failsafe",
                        "--move-timeout", "8", "--out", str(tmp_path / "run"))
        out = Lines(run)
        assert out.wait_for("move 3/", 240), out.text
        assert gcs.armed_now, "flying"
        if how in ("SIGINT", "SIGTERM"):
            sig = signal.SIGINT if how == "SIGINT" else signal.SIGTERM
            os.kill(run.pid, sig)
            run.wait(timeout=240)
            assert run.returncode == 128 + sig, out.text
            assert out.wait_for("landed and disarmed", 5), out.text
        elif how == "kill9":
            run.kill()  # no bring-down: the autopilot's failsafe alone
            run.wait(timeout=10)
        else:
            proxy.cut()
            run.wait(timeout=240)  # the companion notices, commands what it cannot deliver, says so
            assert run.returncode == 1 and "its own failsafe" in out.text, out.text
        assert until(lambda: not gcs.armed_now, 240), f"still armed: {gcs.seen}\n{out.text}"
    finally:
        if run is not None:
            stop_process(run)
        if proxy is not None:
            proxy.stop()
        stop_process(sitl)
        gcs.close()
