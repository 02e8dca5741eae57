"""The operator's three processes for real: `uavsearch sitl`, `uavsearch run`, and a pymavlink
ground station. A small search flies and lands; an interrupted one lands and disarms too."""

import json
import os
import signal
import time
from pathlib import Path

import pytest
from flight_procs import sitl_process, uavsearch
from pymavlink import mavutil

pytestmark = pytest.mark.slow


def test_three_processes_fly_a_small_search(tmp_path: Path) -> None:
    with sitl_process(tmp_path, 8, "--speedup", "8", "--width", "6", "--height", "6", "--targets", "2",
                      "--seed", "4") as (field_file, gcs, _):
        field = json.loads(field_file.read_text())
        assert (field["width"], field["height"], field["targets"]) == (6, 6, 2)
        assert "targets_cells" not in field and field["provenance"]["git_revision"]
        run = uavsearch("run", "--field", str(field_file), "--policy", "frontier", "--max-moves", "10",
                        "--out", str(tmp_path / "run"))
        out, _ = run.communicate(timeout=240)
        assert run.returncode in (0, 3), out  # 3: ended at the move cap short of |R| (said so)
        assert "move 10/10" in out or "found 2/2" in out, "live progress, one line per decision"
        time.sleep(1.0)
        assert gcs.seen.armed[:3] == [False, True, False], gcs.seen
        assert gcs.seen.max_alt_m > 2.5, "it flew"
        assert gcs.seen.landed_state == mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND, "and landed"
    log = json.loads((tmp_path / "run" / "search_log.json").read_text())
    assert log["outcome"]["touchdown"] is None and 1 <= len(log["cells"]) - 1 <= 10
    assert log["outcome"]["exit_code"] == run.returncode
    assert (tmp_path / "run" / "search.png").read_bytes()[:4] == b"\x89PNG", "the companion's own plot"
    tlog = mavutil.mavlink_connection(str(tmp_path / "run" / "companion.tlog"))
    kinds = set()
    while (m := tlog.recv_match()) is not None:
        kinds.add(m.get_type())
    assert {"HEARTBEAT", "COMMAND_LONG", "SET_POSITION_TARGET_LOCAL_NED", "ENCAPSULATED_DATA"} <= kinds


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_mid_search_lands_and_disarms(tmp_path: Path, sig: signal.Signals) -> None:
    with sitl_process(tmp_path, 9, "--speedup", "12") as (field_file, gcs, _):
        run = uavsearch("run", "--field", str(field_file), "--policy", "lawnmower", "--out", str(tmp_path / "run"))
        lines: list[str] = []
        end = time.monotonic() + 180
        while time.monotonic() < end:  # mid-search: a few moves flown
            line = run.stdout.readline()
            lines.append(line)
            if "move 4/" in line or not line:
                break
        assert gcs.armed_now and gcs.seen.alt_m > 2.5, "".join(lines)
        os.kill(run.pid, sig)
        rest, _ = run.communicate(timeout=180)
        out = "".join(lines) + rest
        assert run.returncode == 128 + sig, out
        assert f"interrupted by {sig.name}" in out and "landed and disarmed" in out, out
        time.sleep(1.0)
        assert not gcs.armed_now, gcs.seen  # (relative_alt is GPS-based: metres of vertical error)
        assert gcs.seen.landed_state == mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND
    log = json.loads((tmp_path / "run" / "search_log.json").read_text())
    assert log["outcome"]["exit_code"] == 128 + sig and log["outcome"]["touchdown"]["disarmed"]
    assert log["outcome"]["touchdown"]["commanded"] == ["RTL"]
    assert len(log["cells"]) >= 5


def test_losing_the_vehicle_mid_search_ends_run_with_the_cause(tmp_path: Path) -> None:
    """The SITL dies mid-search: run cannot land what it cannot reach; it must not hang, and must
    say that the vehicle's own failsafe is all that is left."""
    with sitl_process(tmp_path, 12, "--speedup", "6") as (field_file, _, sitl_out):
        run = uavsearch("run", "--field", str(field_file), "--policy", "lawnmower", "--move-timeout", "6",
                        "--out", str(tmp_path / "run"))
        lines: list[str] = []
        end = time.monotonic() + 180
        while time.monotonic() < end:
            line = run.stdout.readline()
            lines.append(line)
            if "move 3/" in line or not line:
                break
        sitl_out.proc.kill()
        t0 = time.monotonic()
        rest, _ = run.communicate(timeout=120)
        waited = time.monotonic() - t0
    out = "".join(lines) + rest
    # the search notices the silence on whatever it was doing: a wait that timed out, or the
    # frame request (asked ahead on the simulated clock) that no vehicle acknowledged
    lost = "timed out" in out or "no COMMAND_ACK" in out
    assert run.returncode == 1 and lost and "STILL ARMED" in out, out
    # bounded: the move timeout, RTL's resends (~22 s), the heartbeat wait, and load
    assert "its own failsafe" in out and waited < 6 + 22 + 5 + 30, f"run gave up in {waited:.0f} s"
    log = json.loads((tmp_path / "run" / "search_log.json").read_text())
    assert log["outcome"]["touchdown"]["disarmed"] is False and len(log["cells"]) >= 4
