"""A companion killed -9 mid-search and resumed, for real: our SITL in this process, `uavsearch
run` as a process on a UDP loopback link, SIGKILL at move 5, `uavsearch run --resume` after
it. Landed by its failsafe meanwhile, the vehicle takes off again and the search goes on from
the journal's cell; the log is the whole search."""

from __future__ import annotations

from pathlib import Path

import pytest

from autopilot_bridge.service.journal import read
from missions.resume_trial import (
    companion,
    kill_at_move,
    search_log,
    start_companion,
    truly_found,
    vehicle,
    wait_until,
)
from sim.gridworld import GridConfig

pytestmark = pytest.mark.slow
BASE_PORT = 28200  # this file's UDP ports: 28200-28203


def test_a_killed_companion_resumes_the_search_after_its_vehicle_landed(tmp_path: Path) -> None:
    grid = GridConfig(width=6, height=6, n_targets=3)
    out = tmp_path / "run"
    with vehicle(tmp_path, 5, BASE_PORT, grid, speedup=12.0) as v:
        run, head = start_companion(v, "--field", str(v.field_file), "--out", str(out), "--seed", "5", "--no-tlog")
        before = "".join(head) + kill_at_move(run, 5)
        assert run.returncode == -9 and ": move 5/" in before, before
        # its offboard-loss failsafe holds, then returns and lands it
        assert wait_until(lambda: v.landed_disarmed, 90), "the vehicle landed by itself"
        run = companion("--resume", str(out), "--no-tlog")
        after, _ = run.communicate(timeout=180)
        found = truly_found(v)
    assert run.returncode == 0, before + after
    assert "resuming the search journaled in" in after and "took off again" in after, after
    log = search_log(out)
    (r,) = log["resumes"]
    assert r["how"] == "took off again" and r["at_move"] in (4, 5) and not r["armed_found"]
    moves = len(log["cells"]) - 1
    assert moves > r["at_move"] and len(log["believed_found"]) == 3 and found == 3, (moves, found)
    steps = [abs(a[0] - b[0]) + abs(a[1] - b[1]) for a, b in zip(log["cells"], log["cells"][1:], strict=False)]
    assert set(steps) <= {0, 1}, "the whole search, one grid move per decision (a resumed one repeats its cell)"
    assert read(out).status == "ended", "a search that ran to its end is not resumed again"
