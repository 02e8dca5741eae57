"""One companion for a fleet (issue 29): N vehicles, each on its own MAVLink link, one shared
belief and the team planner, decisions in rounds.

Why one process for the fleet: the team's belief is one object in memory (the team planner's
SharedBelief, fed every vehicle's view each round), so there is no consensus protocol to run
and nothing to reconcile; the rounds share one clock (this process's), so "every vehicle's
view, then everyone's move" is a barrier, not a distributed agreement; and the separation check
sees every setpoint before it is sent. The alternative, one companion per vehicle exchanging
observations over MAVLink (the lossy/delayed sharing policy.belief.shared.CommsModel models),
is left for later: it needs a message for a view, a rule for late and lost ones, and a
separation rule that works on stale positions.

Each vehicle keeps the whole single-vehicle companion (autopilot_bridge.service.PolicyService:
its link, telemetry intake, GPS estimator, detector, found-targets memory, pilot, map), run on
its own thread; the only thing that differs is its policy, a `VehicleProxy` that hands the
round's observation to the `TeamRound` and blocks until the team planner has chosen every
vehicle's move. So a round is: every vehicle's frame -> its view -> the shared belief -> the
team planner picks one move per vehicle -> the separation check -> each flies its leg.

Separation, in three layers:
- cells: the team planner's rule (policy.team.base.separate): no two vehicles head for one
  cell, none takes a cell another stands on, no swaps;
- heights: not needed under that rule. Moves are one cell north, south, east or west, so legs
  are unit segments of the cell-centre lattice; two of them meet only at a lattice point, and
  the rule forbids a shared destination, a destination another vehicle stands on (it may only
  follow one that is leaving, which keeps a cell's distance while both fly) and a swap. So no
  two legs cross in the air, and every vehicle searches at the height its camera and detector
  are built for (3.5 m);
- setpoints: every new setpoint is checked (`SeparationCheck`) against every other vehicle's
  setpoint and against the vehicles out of the team still in the air (one landing where it was
  lost); one less than MIN_SEPARATION_M horizontally within SAME_HEIGHT_M vertically is
  refused: the vehicle holds its cell this round, and the refusal is counted.
The log records the least horizontal distance seen between airborne vehicles (telemetry,
sampled by `monitor`) and between setpoints.

A vehicle lost (its link silent for LOST_AFTER_S, or disarmed or on the ground while the
search still counts on it) is taken out of the team: its thread's next step raises
`VehicleLost` (missions.fleet_flight brings it down through missions.guarded), the planner
drops it and the others re-plan without it. A stop of the fleet (Ctrl-C, SIGTERM, an exception
in the planner) raises `FleetStop` in every vehicle's thread: each is brought down.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from policy.base import Observation
from policy.team.planner import TeamBeliefPlanner
from sim.gridworld import DELTAS, GridConfig, cell_to_ned

from ..localisation.team_finds import TeamFinds, TeamFoundTargets
from .pilot import DECISION_DEADLINE_S
from .policy_service import HOLD, PolicyService

#: vehicle k searches at the base altitude + k * this (3.5, 5.0, 6.5, 8.0 m): a vehicle whose
#: position estimate is a cell off (its lattice registration on the wrong hypothesis; seen on
#: 20 x 20 seed 2: a vehicle 2 m from where it believed, over another's cell) still passes
#: another 1.5 m or more above or below it, clear of SAME_HEIGHT_M with the height controller's
#: tenths of a metre (at a 1 m step, a 91-move flight saw two vehicles 0.78 m apart horizontally
#: and just under 1 m vertically). The camera's view is built for 3.5 m; higher, the detector
#: and the view scale with the height flown (blobs_to_view), and the frame's cells beyond the
#: 3 x 3 view are left out (20 x 20 seeds 2 and 4 flew the same moves at 1 and 1.5 m steps)
HEIGHT_STEP_M = 1.5
#: setpoints (and vehicles) closer than this horizontally at the same height are refused
MIN_SEPARATION_M = 2.0
#: two heights within this are "the same height" for the separation check
SAME_HEIGHT_M = 1.0
#: a vehicle moving into a cell another is leaving (a follow) starts its leg once the leaver is
#: this far from that cell's centre by its telemetry: started together, a turn out of the cell
#: meets the follower at 0.7 cells (1.4 m), and a leaver slow to start (its thread woken late,
#: its frame late) was met at 0.3 m (4 vehicles, 20 x 20, seed 0, before this rule)
FOLLOW_CLEAR_M = 1.5
#: wall seconds a follower waits for the leaver to clear before it holds instead (refused)
FOLLOW_TIMEOUT_S = 10.0
#: a vehicle whose link has said nothing for this long (wall seconds) is lost
LOST_AFTER_S = 3.0
#: above this height (m over its home) a vehicle counts as airborne for the separation record
AIRBORNE_M = 1.0


class FleetStop(Exception):
    """The fleet's search stops (a signal, an exception elsewhere): bring this vehicle down.
    An Exception, so missions.guarded's bring-down catches it like any failure."""


class VehicleLost(Exception):
    """This vehicle is out of the team (link silent, disarmed, on the ground): bring it down."""


class FleetPlanner(TeamBeliefPlanner):
    """The team belief planner for one flight whose team can shrink: `drop` takes a lost
    vehicle out (perfect sharing: the belief is one row, so what the lost vehicle saw stays in
    it), and `decide` plans for the vehicles left, however many (down to one: the same
    allocation rule, not the single-agent shortcut, so the belief keeps its rows)."""

    #: (1, h, w) searchable cells of a real field (reset_team's mask); None: the rectangle
    mask: np.ndarray | None = None

    def reset_team(self, cfg: GridConfig, n_agents: int, seed: int, mask: np.ndarray | None = None) -> None:
        """mask: (h, w) bool searchable cells of a real field (the vehicles' FieldArea), None:
        the whole rectangle (today's planner, the same streams). On a mask, as the lone belief
        planner on one (policy.planner's _adopt_mask): the belief's prior lives on the
        searchable cells, a masked cell is never a goal (its reveal is 0), and the moves go by
        path lengths around the holes (BFS, sim.gridworld.masks). The allocation still weighs
        goals by Manhattan distance: the FieldArea's mask is one 4-connected part, so every
        searchable cell is reachable, only a little further round a pond than it weighs."""
        if n_agents < 2:
            raise ValueError(f"a fleet flight needs >= 2 vehicles (got {n_agents})")
        if not self.comms.perfect:
            raise ValueError("a fleet flight shares one belief in one process: perfect sharing only")
        self.reset(cfg, 1, n_agents, seed)
        self.members = list(range(n_agents))  # vehicle index of each planner agent
        self.mask = None
        if mask is not None:
            from policy.belief.state import BeliefState
            from policy.planner.planner import _window

            m = np.asarray(mask, bool)
            if m.shape != (cfg.height, cfg.width):
                raise ValueError(f"the fleet's mask is {m.shape}, the field {cfg.height} x {cfg.width}")
            self.mask = m[None]
            density, pair = self.core._prior_cache[(cfg.width, cfg.height, cfg.distribution, cfg.n_targets)]
            self.shared.belief = BeliefState(cfg, 1, density, pair, mask=self.mask)  # perfect sharing: one row
            self.core.belief = self.shared.belief
            viewers = _window(self.mask.astype(np.float64), 1)
            self.core.cell_weight = np.where(viewers > 0, (9.0 / np.maximum(viewers, 1.0)) ** self.params.edge, 0.0)

    def _reveal(self) -> np.ndarray:
        r = super()._reveal()
        return r if self.mask is None else r * self.mask  # a view from a masked cell is no one's to take

    def _moves(self, pos: np.ndarray, goal: np.ndarray, order: np.ndarray, valid: np.ndarray) -> np.ndarray:
        if self.mask is None:
            return super()._moves(pos, goal, order, valid)
        # shortest-path moves on the mask: the goal's BFS field read at each move's next cell
        from policy.team.base import separate
        from sim.gridworld.masks import UNREACHABLE, distance_fields

        h, w = self.cfg.height, self.cfg.width
        a_n = valid.shape[-1]
        nxt = pos[:, :, None, :] + DELTAS[None, None, :a_n]
        cx, cy = np.clip(nxt[..., 0], 0, w - 1), np.clip(nxt[..., 1], 0, h - 1)
        dg = distance_fields(self.mask, goal)  # (1, k, h, w) from each vehicle's goal
        k = self.k
        d0 = dg[0, np.arange(k), pos[0, :, 1], pos[0, :, 0]][None].astype(np.int64)
        d1 = dg[0, np.arange(k)[:, None], cy[0], cx[0]][None].astype(np.int64)
        d1 = np.where(valid, d1, UNREACHABLE)
        rb = self._reveal_b[self._brow]
        gain = rb[np.zeros((1, 1, 1), np.int64), np.arange(k)[None, :, None], cy, cx]
        key = self.params.tie_reveal * gain + self.rng.random(gain.shape) * 1e-6
        prefs = np.where(d1 < d0[..., None], 1e6 + key, np.where(d1 == d0[..., None], 1e3 + key, key))
        return separate(pos, prefs, valid, order)

    def drop(self, vehicle: int) -> None:
        if vehicle not in self.members:
            return
        j = self.members.index(vehicle)
        self.members.pop(j)
        self.k = len(self.members)
        self.shared.n_agents = self.k
        self._brow = np.delete(self._brow, j, axis=1)

    def decide(self, views: np.ndarray, positions: np.ndarray, valid: np.ndarray, t: int) -> np.ndarray:
        """(k,) moves for the members, in `members` order: views (k, 3, 3, 3), positions (k, 2)."""
        pos = np.asarray(positions, np.int64)[None]
        self.shared.update(np.asarray(views)[None], pos, np.array([t]), np.array([True]))
        goal, order = self._allocate(pos)
        return self._moves(pos, goal, order, np.asarray(valid)[None])[0]


@dataclass
class FleetLog:
    """What the fleet's companion records beyond each vehicle's SearchLog."""

    rounds: int = 0
    #: (round, vehicle, cell) of each target the team found (a vehicle over one another found
    #: before is not a find: `duplicate_finds`)
    finds: list[tuple[int, int, tuple[int, int]]] = field(default_factory=list)
    duplicate_finds: int = 0
    #: setpoints refused by the separation check (the vehicle held its cell)
    separation_refused: int = 0
    #: follows (a move into a cell another was leaving) and the wall seconds they waited for it to clear
    follows: int = 0
    follow_wait_s: float = 0.0
    min_setpoint_separation_m: float = float("inf")
    #: the least horizontal distance between two airborne vehicles by their telemetry
    min_separation_m: float = float("inf")
    #: per vehicle: the round it was lost at and why (None: flew to the end)
    lost: dict[int, tuple[int, str]] = field(default_factory=dict)
    #: per round: every member's cell (vehicle -> [x, y])
    cells: list[dict[int, list[int]]] = field(default_factory=list)
    stop_cause: str | None = None
    #: the shared finds (recorded as `TeamFinds.to_dict`: each find, and per vehicle the
    #: teammates' finds it saw, those under its camera, and its registrations on them); None:
    #: finds not shared
    team_finds: TeamFinds | None = None

    def to_dict(self) -> dict[str, Any]:
        inf = float("inf")
        return {"rounds": self.rounds, "finds": [[r, v, list(c)] for r, v, c in self.finds],
                "duplicate_finds": self.duplicate_finds, "separation_refused": self.separation_refused,
                "follows": self.follows, "follow_wait_s": round(self.follow_wait_s, 3),
                "min_setpoint_separation_m": None if self.min_setpoint_separation_m == inf
                else round(self.min_setpoint_separation_m, 3),
                "min_separation_m": None if self.min_separation_m == inf else round(self.min_separation_m, 3),
                "lost": {str(k): {"round": r, "why": w} for k, (r, w) in self.lost.items()},
                "cells": [{str(k): v for k, v in c.items()} for c in self.cells], "stop_cause": self.stop_cause,
                "team_finds": None if self.team_finds is None else self.team_finds.to_dict()}


class SeparationCheck:
    """The setpoint rule: a point (field north, east, down) closer than min_m horizontally to
    another within same_height_m vertically is refused."""

    def __init__(self, min_m: float = MIN_SEPARATION_M, same_height_m: float = SAME_HEIGHT_M) -> None:
        if not (min_m > 0 and same_height_m > 0):
            raise ValueError(f"separation limits must be > 0 m (got {min_m}, {same_height_m})")
        self.min_m, self.same_height_m = min_m, same_height_m

    def nearest(self, p: np.ndarray, others: list[np.ndarray]) -> float:
        """The least horizontal distance from p to the others at its height (inf: none)."""
        d = [float(np.hypot(*(p[:2] - q[:2]))) for q in others if abs(float(p[2] - q[2])) < self.same_height_m]
        return min(d, default=float("inf"))

    def allows(self, p: np.ndarray, others: list[np.ndarray]) -> bool:
        return self.nearest(p, others) >= self.min_m


class VehicleProxy:
    """Vehicle i's policy as its PolicyService sees it: `act` takes part in the team's round."""

    name = "belief-team"
    needs_truth = False
    off_map = "random"
    #: the lone loop's "found every target" is the team's, told in the round: a vehicle that found
    #: them all itself (seed 1 on a 2-target paddock) otherwise broke off before the team heard of
    #: its last find, and the other searched to the move cap for a target already found
    team_counts_finds = True

    def __init__(self, team: TeamRound, index: int) -> None:
        self.team, self.index = team, index
        self.finished = False

    def reset(self, cfg: GridConfig, n: int, seed: int) -> None:  # the team planner was reset once, for all
        pass

    def act(self, obs: Observation) -> np.ndarray:
        return np.array([self.team.submit(self.index, obs)])


class GuardedFrames:
    """Vehicle i's frame source, raising FleetStop / VehicleLost at the next capture once the
    fleet stops or the vehicle is out (a thread waiting for a settled arrival that will never
    come would otherwise wait out its move timeout)."""

    def __init__(self, frames: Any, team: TeamRound, index: int) -> None:
        self._frames, self._team, self._index = frames, team, index

    def capture(self, t: float):
        self._team.check(self._index)
        return self._frames.capture(t)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._frames, name)


class TeamRound:
    """The fleet's decision barrier: each vehicle's thread submits its observation; the last to
    arrive runs the team planner for everyone, the separation check, and wakes the others."""

    def __init__(self, n: int, planner: FleetPlanner, grid: GridConfig,
                 separation: SeparationCheck | None = None, round_timeout_s: float = 30.0,
                 share_finds: bool = True) -> None:
        """n vehicles; their services are attached (`attach`) once built, their frame sources
        being this round's GuardedFrames. share_finds: every vehicle's finds are landmarks for
        the others (`attach`; False: each knows its own only, as before issue 29's fix)."""
        self.services: list[PolicyService] = []
        self.planner, self.grid = planner, grid
        self.sep = separation or SeparationCheck()
        self.round_timeout_s = round_timeout_s
        self.n = n
        self.log = FleetLog()
        self.proxies = [VehicleProxy(self, i) for i in range(self.n)]
        self.alive = set(range(self.n))  # taking part in the rounds
        self._pending: dict[int, Observation] = {}
        self._result: dict[int, int] = {}
        self._round = 0
        self._found: set[tuple[int, int]] = set()
        self._why_lost: dict[int, str] = {}
        self._submitted = [0] * n  # rounds each vehicle took part in
        self._follow: dict[int, tuple[int, np.ndarray]] = {}  # follower -> (leaver, its destination NE)
        self.stop_cause: str | None = None
        self.finished = False
        self._cv = threading.Condition()
        #: the team's finds, shared by the vehicles' found-targets memories (None: not shared)
        self.team_finds: TeamFinds | None = TeamFinds() if share_finds else None
        self.log.team_finds = self.team_finds

    def attach(self, services: list[PolicyService]) -> None:
        """The vehicles' services, in vehicle order. With shared finds, each service's
        found-targets memory becomes a `TeamFoundTargets` on the team's registry (its
        registration reads the same one): a teammate's find is then no new find to it, and a
        landmark for its position (autopilot_bridge.localisation.team_finds says why). Done
        before any search starts, so nothing is in the memories it replaces."""
        if len(services) != self.n:
            raise ValueError(f"{len(services)} services for a team of {self.n}")
        self.services = list(services)
        if self.team_finds is None:
            return
        for i, s in enumerate(self.services):
            if len(s.found):
                raise ValueError(f"vehicle {i} has found targets before its team's search started")
            shared = TeamFoundTargets(s.spec, s.estimator, s.intake, self.team_finds, i, s.det.fov_deg)
            shared.camera_height = s.found.camera_height
            s.found = s.registration.found = shared

    # -- vehicle threads ----------------------------------------------------------------
    def check(self, i: int) -> None:
        """Raise what stops vehicle i now, if anything."""
        if self.stop_cause is not None:
            raise FleetStop(self.stop_cause)
        if i in self._why_lost:
            raise VehicleLost(self._why_lost[i])

    def submit(self, i: int, obs: Observation) -> int:
        with self._cv:
            self.check(i)
            self._pending[i] = obs
            self._submitted[i] += 1
            mine = self._round
            if self.alive <= set(self._pending):
                self._decide()
            waited = time.monotonic()
            while self._round == mine:
                self._cv.wait(0.2)
                self.check(i)
                self.services[i].pilot.expect(DECISION_DEADLINE_S)  # waiting for the team is not a hung loop
                if self._round == mine and time.monotonic() - waited > self.round_timeout_s:
                    for j in sorted(self.alive - set(self._pending)):
                        self._lose(j, f"no observation for round {mine} within {self.round_timeout_s:.0f} s")
                    if self.alive <= set(self._pending):
                        self._decide()
            self.check(i)
            if self.finished:
                self.proxies[i].finished = True
            a = self._result.get(i, HOLD)
            follow = self._follow.pop(i, None)
        if follow is not None and a != HOLD and not self._cleared(i, *follow):
            with self._cv:
                self.log.separation_refused += 1
            return HOLD
        return a

    def _cleared(self, i: int, j: int, dest_ne: np.ndarray) -> bool:
        """Wait (outside the lock) until vehicle j, leaving the cell vehicle i moves into, is
        FOLLOW_CLEAR_M from its centre; False where it does not clear in time or is lost."""
        t0 = time.monotonic()
        with self._cv:
            self.log.follows += 1
        try:
            while time.monotonic() - t0 < FOLLOW_TIMEOUT_S:
                self.check(i)
                if j not in self.alive:
                    return False  # lost where it was: landing in that cell
                p = self._position(self.services[j])
                if p is not None and float(np.hypot(*(p[:2] - dest_ne))) >= FOLLOW_CLEAR_M:
                    return True
                self.services[i].pilot.expect(DECISION_DEADLINE_S)
                time.sleep(0.01)
            return False
        finally:
            with self._cv:
                self.log.follow_wait_s += time.monotonic() - t0

    def leave(self, i: int, why: str | None = None) -> None:
        """Vehicle i's thread ended (its search returned or failed): the others go on without it."""
        with self._cv:
            if i in self.alive and why is not None and i not in self._why_lost:
                self._why_lost[i] = why
                self.log.lost[i] = (self._round, why)
            self._drop(i)

    def stop(self, cause: str) -> None:
        """Stop every vehicle (each brought down by its thread)."""
        with self._cv:
            if self.stop_cause is None:
                self.stop_cause = self.log.stop_cause = cause
            self._cv.notify_all()

    # -- the watch (the fleet's main thread) -----------------------------------------------
    def monitor(self) -> None:
        """Lose the vehicles the search counts on that are silent, disarmed or on the ground,
        and record the least separation between airborne vehicles."""
        now = time.monotonic()
        air: list[np.ndarray] = []
        for i, s in enumerate(self.services):
            tel = s.link.telemetry
            # searching: it has taken part in a round, and has not logged a decision it did not
            # submit (its own end of the search: the move cap, then its landing)
            searching = 0 < self._submitted[i] == len(s.log.cells)
            if i in self.alive and searching and not self.finished:
                if tel.heartbeat_time and now - tel.heartbeat_time > LOST_AFTER_S:
                    self.lose(i, f"link silent for {now - tel.heartbeat_time:.1f} s")
                elif not tel.armed:
                    self.lose(i, "disarmed during the search")
            p = self._position(s)
            if p is not None and -p[2] - self._home_down(s) > AIRBORNE_M:
                air.append(p)
        for a in range(len(air)):
            for b in range(a + 1, len(air)):
                self.log.min_separation_m = min(self.log.min_separation_m, float(np.hypot(*(air[a][:2] - air[b][:2]))))

    def lose(self, i: int, why: str) -> None:
        with self._cv:
            if i not in self.alive:
                return
            self._lose(i, why)
            if self._pending and self.alive and self.alive <= set(self._pending):
                self._decide()
            self._cv.notify_all()

    # -- inside the lock ---------------------------------------------------------------
    def _lose(self, i: int, why: str) -> None:
        self._why_lost[i] = why
        self.log.lost[i] = (self._round, why)
        self._drop(i)

    def _drop(self, i: int) -> None:
        self.alive.discard(i)
        self._pending.pop(i, None)
        self.planner.drop(i)
        if self._pending and self.alive and self.alive <= set(self._pending):
            self._decide()
        self._cv.notify_all()

    def _decide(self) -> None:
        try:
            self._plan()
        except Exception as e:  # noqa: BLE001 - a failing planner stops the fleet: every vehicle lands
            self.stop_cause = self.log.stop_cause = f"team planner failed: {type(e).__name__}: {e}"
        self._pending.clear()
        self._round += 1
        self.log.rounds = self._round
        self._cv.notify_all()

    def _plan(self) -> None:
        members = [i for i in self.planner.members if i in self._pending]
        obs = {i: self._pending[i] for i in members}
        cells = {i: np.asarray(obs[i].positions[0], np.int64) for i in members}
        self.log.cells.append({i: [int(c[0]), int(c[1])] for i, c in cells.items()})
        for i in members:
            if float(obs[i].found_now[0]) > 0 if obs[i].found_now is not None else False:
                c = (int(cells[i][0]), int(cells[i][1]))
                if c in self._found:
                    self.log.duplicate_finds += 1
                else:
                    self._found.add(c)
                    self.log.finds.append((self._round, i, c))
        self._result = {}
        self._follow = {}
        if len(self._found) >= self.grid.n_targets:
            self.finished = True
            self._result = dict.fromkeys(members, HOLD)
            return
        a = self.planner.decide(np.stack([obs[i].views[0] for i in members]), np.stack([cells[i] for i in members]),
                                np.stack([obs[i].valid[0] for i in members]), self._round)
        # each vehicle's search height (field down): its own (distinct heights: missions.fleet_flight)
        height = {i: self._home_down(self.services[i]) - self.services[i].spec.altitude_m for i in members}
        dest = {i: np.array([*cell_to_ned(cells[i] + DELTAS[int(a[j])]), height[i]]) for j, i in enumerate(members)}
        # the vehicles out of the team that are still in the air (landing where they were lost)
        outside = [p for j, s in enumerate(self.services) if j not in self.alive
                   for p in [self._position(s)] if p is not None and -p[2] - self._home_down(s) > AIRBORNE_M]
        self._result = {i: int(a[j]) for j, i in enumerate(members)}
        changed = True
        while changed:  # a hold changes that vehicle's setpoint: check the others against it again
            changed = False
            for i in members:
                if self._result[i] == HOLD:
                    continue
                others = [dest[m] for m in members if m != i] + outside
                if not self.sep.allows(dest[i], others):  # held: its setpoint stays its cell's centre
                    self.log.separation_refused += 1
                    self._result[i] = HOLD
                    dest[i] = np.array([*cell_to_ned(cells[i]), height[i]])
                    changed = True
        for i in members:
            others = [dest[m] for m in members if m != i] + outside
            self.log.min_setpoint_separation_m = min(self.log.min_setpoint_separation_m,
                                                     self.sep.nearest(dest[i], others))
            if self._result[i] != HOLD:  # a follow: into the cell another is leaving
                for m in members:
                    if m != i and np.array_equal(cells[m], cells[i] + DELTAS[self._result[i]]):
                        self._follow[i] = (m, dest[i][:2].copy())

    def _position(self, s: PolicyService) -> np.ndarray | None:
        """Vehicle s's (north, east, down) in the field frame by its latest telemetry (down
        from the field's origin altitude); None before it has told one."""
        loc = s.link.telemetry.local
        if not loc or not (s.link.telemetry.local_origin or s.link.telemetry.home):
            return None
        return np.array([loc["n"], loc["e"], loc["d"]]) + s.intake.local_origin_in_field()

    def _home_down(self, s: PolicyService) -> float:
        return float(s.intake.home_in_field()[2]) if s.link.telemetry.home else 0.0
