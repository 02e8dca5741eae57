"""The search journal reloads exactly: every flyable policy's own state round-trips through the
pickle-free snapshot and decides the same afterwards; a real flight's journal, loaded into a
fresh service, saves again to the same state, and its policy takes the flight's next actions;
a journal that is missing, corrupt or another search's is refused naming the file."""

from __future__ import annotations

import copy
import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.journal import (
    JOURNAL,
    Journal,
    JournalError,
    LoopState,
    load,
    read,
    save,
    state_of,
)
from autopilot_bridge.service.policy_service import PolicyService, SearchSpec
from autopilot_bridge.service.snapshot import restore, snapshot
from missions.flight_policy import flight_policy
from policy.base import Observation, Policy, observe
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes
from sim.gridworld.geodesy import HomePosition

#: this file's UDP ports (28000-28999 are the resume tests')
FLIGHT_PORT = 28100
IDLE_PORT = 28110

FLYABLE = ["belief", "searchnet", "drqn", "dualstream", "ssn", "ns", "frontier", "lawnmower", "random"]


def _same(tree_a: dict, arrays_a: dict, tree_b: dict, arrays_b: dict) -> bool:
    return (json.dumps(tree_a) == json.dumps(tree_b) and arrays_a.keys() == arrays_b.keys()
            and all(np.array_equal(arrays_a[k], arrays_b[k]) and arrays_a[k].dtype == arrays_b[k].dtype
                    for k in arrays_a))


@pytest.mark.parametrize("name", FLYABLE)
def test_a_policys_state_round_trips_and_decides_the_same(name: str) -> None:
    g = GridConfig()
    p = flight_policy(name, None, g, 7)
    p.reset(g, 1, 7)
    world = BatchGridWorld(sample_episodes(g, 1, 7), 7)
    for _ in range(6):
        world.step(p.act(observe(world)))
    tree, arrays = snapshot(p, "policy")
    q = flight_policy(name, None, g, 7)
    q.reset(g, 1, 7)
    restore(q, json.loads(json.dumps(tree)), {k: v.copy() for k, v in arrays.items()}, "policy")
    assert _same(tree, arrays, *snapshot(q, "policy")), "saved again: the same state"
    for _ in range(20):  # the next 20 moves (or the episode's rest): the same decisions
        if world.done.all():
            break
        obs = observe(world)
        a = p.act(obs)
        assert np.array_equal(q.act(obs), a)
        world.step(a)


class Recording(Policy):
    """A flight's policy with its observations and actions kept, to replay them afterwards."""

    journal_skip = ("calls",)

    def __init__(self, inner: Policy) -> None:
        self.inner, self.name, self.calls = inner, inner.name, []

    def reset(self, cfg, n, seed, episodes=None) -> None:
        self.inner.reset(cfg, n, seed, episodes)

    def act(self, obs: Observation) -> np.ndarray:
        a = self.inner.act(obs)
        self.calls.append((copy.deepcopy(obs), np.array(a)))
        return a


def test_a_flights_journal_reloads_exactly(tmp_path: Path) -> None:
    """A real search over MAVLink (our SITL, 6 x 6, belief planner) journaled at every decision;
    the journal of move 4 loaded into a fresh service (another link, no vehicle) saves again to
    the same state, and the restored policy takes every later action the flight took."""
    _journal_reloads_exactly(tmp_path, GridConfig(width=6, height=6, n_targets=3), 4, FLIGHT_PORT, IDLE_PORT)


def test_a_journal_with_altitude_levels_reloads_the_level_it_flies(tmp_path: Path) -> None:
    """The same with altitude levels (10 x 10 / 3, L = 3: the soft-evidence belief): the journal
    holds the level of the next move, so a resumed search rejoins at its height."""
    fresh, log = _journal_reloads_exactly(tmp_path, GridConfig(width=10, height=10, n_targets=3, levels=3), 1,
                                          28300, 28310)  # 27100-27199: the video tests
    assert fresh.height.level == log.levels_flown[4] == 2, (fresh.height.level, log.levels_flown)


def _journal_reloads_exactly(tmp_path: Path, grid: GridConfig, seed: int, flight_port: int,
                             idle_port: int) -> tuple[PolicyService, object]:
    """Fly, journal every decision, reload move 4's journal into a fresh service and check it
    saves the same state and decides the same; returns (the fresh service, the flight's log)."""
    from missions.flight import _truth_sitl
    from sim.mavlink import SitlConfig

    cfg = SitlConfig(speedup=12.0, camera=True, grid=dataclasses.replace(grid, levels=1, detection=None),
                     episode_seed=seed, seed=seed, companion_lockstep=True,
                     api_local_port=flight_port, api_remote_port=flight_port + 1, gcs_link=False, bind="127.0.0.1")
    sitl = _truth_sitl(cfg).start()
    link = VehicleLink(f"udpin:127.0.0.1:{flight_port + 1}")
    spec = SearchSpec(origin=sitl.field_origin, grid=grid, max_moves=8, field_edge=True)
    try:
        svc = PolicyService(link, Recording(flight_policy("belief", None, grid, seed)), spec, seed=seed)
        journal = Journal(tmp_path / "run", svc, {"test": True})

        def keep(move: int, cell: np.ndarray, t_k: float) -> None:
            journal(move, cell, t_k)
            shutil.copytree(tmp_path / "run", tmp_path / f"at-{move}")

        svc.journal = keep
        svc.take_off()
        log = svc.run()
        svc.land()
    finally:
        link.close()
        sitl.stop()
    moves = len(log.cells) - 1
    assert moves >= 5 and journal.writes == moves, "one journal per decision flown on"
    k = 4
    doc = read(tmp_path / f"at-{k}")
    assert doc.loop.move == k and doc.loop.cell == tuple(log.cells[k]) and doc.status == "searching"
    assert doc.meta["provenance"]["git_revision"] and doc.meta["provenance"]["config"] == {"test": True}
    idle = VehicleLink(f"udpin:127.0.0.1:{idle_port}")
    try:
        fresh = PolicyService(idle, Recording(flight_policy("belief", None, grid, seed)), spec, seed=seed)
        loop = load(tmp_path / f"at-{k}", fresh)
        assert loop == LoopState(k, tuple(log.cells[k]), doc.loop.t_k)
        assert fresh.log.cells == log.cells[:k]
        save(tmp_path / "again", fresh, loop)
        again = read(tmp_path / "again")
        assert json.dumps(again.meta["state"]) == json.dumps(doc.meta["state"]), "saved again: the same state"
        from autopilot_bridge.service.journal import _arrays

        a, b = _arrays(doc), _arrays(again)
        assert a.keys() == b.keys() and all(np.array_equal(a[x], b[x]) for x in a)
        tree, arrays = state_of(fresh)
        assert json.dumps(tree) == json.dumps(doc.meta["state"])
        # the flight's decisions from move k on, replayed into the restored policy: the same
        calls = svc.policy.calls
        assert len(calls) > k
        for obs, act in calls[k:]:
            assert np.array_equal(fresh.policy.inner.act(obs), act)
    finally:
        idle.close()
    return fresh, log


def _journal(tmp: Path, grid: GridConfig, policy: str = "frontier", status: str = "searching") -> Path:
    """A journal as `uavsearch run` writes it, of a service that has not flown (no vehicle)."""
    link = VehicleLink(f"udpin:127.0.0.1:{IDLE_PORT + 1}")
    try:
        origin = HomePosition(51.45, -2.58, 30.0)
        svc = PolicyService(link, flight_policy(policy, None, grid, 0), SearchSpec(origin=origin, grid=grid), 0)
        svc.policy.reset(grid, 1, 0)
        config = {"connect": f"udpin:127.0.0.1:{IDLE_PORT + 2}", "field": None, "grid": grid.to_dict(),
                  "origin": [origin.lat_deg, origin.lon_deg, origin.alt_m], "policy": policy, "checkpoint": None,
                  "altitude": 3.5, "max_moves": None, "on_abort": "rtl", "field_edge": False}
        save(tmp, svc, LoopState(3, (1, 2), 40.0), config, status)
    finally:
        link.close()
    return tmp


_WRITER = """
import sys
from pathlib import Path
from autopilot_bridge.service.journal import LoopState, save
from autopilot_bridge.link.connection import VehicleLink
from autopilot_bridge.service.policy_service import PolicyService, SearchSpec
from missions.flight_policy import flight_policy
from sim.gridworld import GridConfig
from sim.gridworld.geodesy import HomePosition
grid = GridConfig(width=6, height=6, n_targets=2)
link = VehicleLink(sys.argv[2])
svc = PolicyService(link, flight_policy("belief", None, grid, 0), SearchSpec(HomePosition(51.45, -2.58, 30.0), grid), 0)
svc.policy.reset(grid, 1, 0)
print("writing", flush=True)
move = 0
while True:
    svc.log.cells.append((move % 6, 0))
    save(Path(sys.argv[1]), svc, LoopState(move, (move % 6, 0), 4.0 * move))
    move += 1
"""


def test_a_journal_killed_mid_write_still_loads(tmp_path: Path) -> None:
    """kill -9 at random instants of a process writing journals back to back: each time the
    journal left loads whole (the old pair or the new one, never half of either)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    rng = np.random.default_rng(11)
    moves = []
    for i in range(2):
        p = subprocess.Popen([sys.executable, "-c", _WRITER, str(tmp_path / "j"), f"udpin:127.0.0.1:{IDLE_PORT + 5 + i}"],
                             stdout=subprocess.PIPE, text=True, env={**os.environ})
        assert p.stdout.readline().strip() == "writing"
        time.sleep(0.3 + float(rng.random()))
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
        doc = read(tmp_path / "j")
        from autopilot_bridge.service.journal import _arrays

        _arrays(doc)  # whole, with its SHA-256
        assert len(doc.meta["state"]["service"]["log"]["cells"]) == doc.loop.move + 1
        moves.append(doc.loop.move)
    assert min(moves) > 2, f"it wrote journals before each kill ({moves})"


def _text(output: str) -> str:
    return " ".join(output.replace("│", " ").split())


def test_a_bad_journal_is_refused_naming_the_file(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from missions.cli import app

    runner = CliRunner()
    grid = GridConfig(width=6, height=6, n_targets=2)

    def refused(d: Path, *words: str, args: tuple[str, ...] = ()) -> None:
        r = runner.invoke(app, ["run", "--resume", str(d), *args], env={"COLUMNS": "400"})
        assert r.exit_code == 2 and all(w in _text(r.output) for w in words), (words, r.output)

    refused(tmp_path / "none", "none/journal.json", "does not exist")
    d = _journal(tmp_path / "ok", grid)
    refused(d, "--policy", "policy 'frontier'", args=("--policy", "belief"))
    refused(d, "--width", "width 6", args=("--width", "8"))
    refused(d, "--seed", "seed 0", args=("--seed", "5"))
    # another field's file given beside the journal
    from missions.fieldfile import FieldSpec, write_field

    write_field(tmp_path / "f.json", FieldSpec(HomePosition(51.0, -2.0, 30.0), grid))
    refused(d, "f.json", "not the journaled search's", args=("--field", str(tmp_path / "f.json")))
    # the arrays file changed under the journal: refused when loaded
    bad = tmp_path / "bad"
    shutil.copytree(d, bad)
    npz = next(bad.glob("journal-*.npz"))
    npz.write_bytes(npz.read_bytes()[:-10] + b"0123456789")
    with pytest.raises(JournalError, match=r"journal-00003\.npz.*SHA-256"):
        from autopilot_bridge.service.journal import _arrays

        _arrays(read(bad))
    (bad / JOURNAL).write_text('{"kind": "uavsearch journal", "format": 1, "sta')
    refused(bad, "bad/journal.json", "not readable JSON")
    refused(_journal(tmp_path / "ended", grid, status="ended"), "ran to its end")
    # a journal loaded into a service of another policy or field: refused, naming the file
    link = VehicleLink(f"udpin:127.0.0.1:{IDLE_PORT + 3}")
    try:
        spec = SearchSpec(origin=HomePosition(51.45, -2.58, 30.0), grid=grid)
        with pytest.raises(JournalError, match=r"ok/journal\.json.*policy"):
            load(d, PolicyService(link, flight_policy("lawnmower", None, grid, 0), spec, 0))
        spec8 = SearchSpec(origin=spec.origin, grid=GridConfig(width=8, height=6, n_targets=2))
        with pytest.raises(JournalError, match=r"ok/journal\.json.*grid"):
            load(d, PolicyService(link, flight_policy("frontier", None, spec8.grid, 0), spec8, 0))
    finally:
        link.close()
    # a new search into a directory whose search has not ended: it says how to go on with it
    r = runner.invoke(app, ["run", "--field", str(tmp_path / "f.json"), "--out", str(d)], env={"COLUMNS": "400"})
    assert r.exit_code == 2 and "--resume" in _text(r.output) and "3 moves" in _text(r.output), r.output


def test_rejoin_refuses_a_restarted_vehicle_and_takes_a_landed_one_off_again(tmp_path: Path) -> None:
    """A vehicle whose clock is behind the journal's has restarted: refused, naming the journal.
    One on the ground with its clock on: armed, taken off, in OFFBOARD, the next decision on
    the journal's lattice a period ahead of its clock."""
    from autopilot_bridge.service.resume import rejoin
    from provenance import atomic_write_json
    from sim.mavlink import Sitl, SitlConfig

    grid = GridConfig(width=6, height=6, n_targets=2)
    sitl = Sitl(SitlConfig(speedup=4.0, physics="kinematic", camera=False, gcs_link=False, grid=grid,
                           api_local_port=IDLE_PORT + 8, api_remote_port=IDLE_PORT + 9, bind="127.0.0.1")).start()
    link = VehicleLink(f"udpin:127.0.0.1:{IDLE_PORT + 9}")
    try:
        svc = PolicyService(link, flight_policy("frontier", None, grid, 0), SearchSpec(sitl.field_origin, grid), 0)
        svc.policy.reset(grid, 1, 0)
        save(tmp_path, svc, LoopState(3, (1, 2), 2.0))
        doc = read(tmp_path)
        atomic_write_json(doc.path, {**doc.meta, "vehicle": {**doc.meta["vehicle"], "sim_time_s": 1e6}})
        with pytest.raises(JournalError, match=r"journal\.json.*restarted"):
            rejoin(svc, read(tmp_path), doc.loop, timeout=20)
        r = rejoin(svc, doc, doc.loop, timeout=30)
        assert r.how == "took off again" and not r.armed_found
        link.wait_for(lambda: link.telemetry.mode == "OFFBOARD", 5.0, "OFFBOARD in the heartbeat")
        assert link.telemetry.armed and -link.telemetry.local["d"] > 2.5, "in the air"
        now = svc.intake.local_history[-1][0]
        assert (r.t_k - 2.0) % 4.0 == pytest.approx(0.0) and now + 4.0 <= r.t_k + 0.5 < now + 8.5
    finally:
        svc.stop_setpoints()
        link.close()
        sitl.stop()
