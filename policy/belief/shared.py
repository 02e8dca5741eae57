"""One belief for a team (issue 29): every agent's observations fused into BeliefState, with a
communication model where sharing is delayed or lossy.

Why BeliefState itself: a view is evidence about the cells it shows whoever took it, so the
team's belief is the same filter fed N views per joint step (one update per agent, the same
time t: the second and later updates of a step advance nothing). The attribution rule already
handles two agents seeing one target: whoever stands on it finds it (the centre slot), a view
from beside it after that sees a found target (found > 0 there), before it an unfound one.

Communication (CommsModel): an agent's own observation enters its belief at once; another
agent's observation of step s arrives at step s + delay, or never (lost with probability loss,
one draw per message, seeded). Then every agent keeps its own copy of the belief: a
BeliefState with n * N rows (row e * N + i: agent i of episode e). A late observation of static
targets is folded in at the time it arrives, as if taken then: exact (a cell's targets do not
change, only whether they are found, which the attribution rule reads from the belief). For
moving targets a late view is dropped (folded as if current it misled the filter: the targets
moved on). Agents' positions are assumed known to the team at all times (a short-range beacon,
as ADS-B or Remote ID: the separation rule needs them); only the observations are delayed or
lost. With CommsModel.beacons the positions also inform each copy (static targets): the cells
other agents' views showed are theirs to report (covered), the cells they stood on hold no
unfound target (_settle).
Perfect sharing (delay 0, loss 0) keeps one copy per episode (n rows): the same numbers as
N copies fed the same messages, N times cheaper.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.gridworld import GridConfig

from ..base import Observation
from .state import BeliefState


@dataclass(frozen=True)
class CommsModel:
    """How the agents' observations reach each other: each message arrives `delay` joint
    steps after it was sent, or is lost with probability `loss` (independently per sender,
    receiver and step, seeded). A message carries the sender's last `history` observations
    (1: only the one it took that step), so a lost one can come with a later message."""

    delay: int = 0
    loss: float = 0.0
    history: int = 1
    #: the beacons' positions (always known: separation needs them) also inform the belief:
    #: cells other agents' views showed are theirs to report (SharedBelief.covered) and cells
    #: they stood on hold no unfound target (SharedBelief._settle); False: views only
    beacons: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.delay, int) and 0 <= self.delay <= 1000):
            raise ValueError(f"CommsModel.delay must be an int in 0..1000 joint steps (got {self.delay!r})")
        if not (math.isfinite(self.loss) and 0.0 <= self.loss < 1.0):
            raise ValueError(f"CommsModel.loss must be in [0, 1) (got {self.loss!r})")
        if not (isinstance(self.history, int) and 1 <= self.history <= 64):
            raise ValueError(f"CommsModel.history must be an int in 1..64 observations (got {self.history!r})")

    @property
    def perfect(self) -> bool:
        return self.delay == 0 and self.loss == 0.0

    def label(self) -> str:
        if self.perfect:
            return "perfect"
        extra = f", each message repeats the last {self.history}" if self.history > 1 else ""
        extra += "" if self.beacons else ", views only (no inference from the beacons)"
        return f"{self.loss * 100:g} % lost, {self.delay}-step delay{extra}"


def comms_rng(seed: int) -> np.random.Generator:
    """The stream that decides which messages are lost."""
    return np.random.default_rng([seed, 0xC0FFEE])


class SharedBelief:
    """The team's belief over n episodes of N agents. `belief` is the BeliefState (n rows when
    sharing is perfect, n * N otherwise); `row(i)` the rows agent i plans on."""

    def __init__(self, cfg: GridConfig, n: int, n_agents: int, prior: np.ndarray | None = None,
                 pair: np.ndarray | None = None, comms: CommsModel | None = None, seed: int = 0) -> None:
        if n_agents < 1:
            raise ValueError(f"n_agents must be >= 1 (got {n_agents})")
        self.cfg, self.n, self.n_agents = cfg, n, n_agents
        self.comms = comms or CommsModel()
        self.shared = self.comms.perfect or n_agents == 1
        rows = n if self.shared else n * n_agents
        self.belief = BeliefState(cfg, rows, prior, pair)
        self.rng = comms_rng(seed)
        #: every joint step's observations so far (views (n, N, 3, 3, 3), positions (n, N, 2),
        #: active (n,)), kept for the last delay + history steps
        self._sent: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._step = -1
        #: (n, N, N) [e, j, i]: the latest step of sender j's observations receiver i has folded
        self._last = np.full((n, n_agents, n_agents), -1, np.int64)
        #: (n, N, N) messages delivered / lost so far, [e, j, i] = sender j to receiver i
        self.delivered = np.zeros((n, n_agents, n_agents), np.int64)
        self.lost = np.zeros((n, n_agents, n_agents), np.int64)
        #: (rows, h, w) bool: cells some other agent's view has shown, known from the beacons'
        #: positions alone (what it saw there may be late or lost); None while sharing is perfect
        #: (then the belief itself has every view) or the beacons are not used (comms.beacons)
        self.covered: np.ndarray | None = None
        #: (rows, h, w) bool: cells some other agent has stood on (beacons); None likewise
        self.trodden: np.ndarray | None = None
        if not self.shared and self.comms.beacons:
            self.covered = np.zeros((rows, cfg.height, cfg.width), bool)
            self.trodden = np.zeros((rows, cfg.height, cfg.width), bool)

    def row(self, i: int) -> np.ndarray:
        """(n,) the belief rows agent i plans on."""
        e = np.arange(self.n)
        return e if self.shared else e * self.n_agents + i

    def _fold(self, views: np.ndarray, positions: np.ndarray, t: np.ndarray, active: np.ndarray) -> None:
        b = self.belief
        zeros = np.zeros((b.n, 1, 1, 1), np.float32)  # maps: unused by the static grid update
        valid = np.ones((b.n, 4), bool)
        b.update(Observation(views=views, maps=zeros, positions=positions, valid=valid, t=t, active=active))

    def _cover(self, positions: np.ndarray, active: np.ndarray) -> None:
        """Mark, for every agent's copy, the cells the other agents' 3 x 3 views show now."""
        n, k, (h, w) = self.n, self.n_agents, (self.cfg.height, self.cfg.width)
        win = np.zeros((n, k, h, w), np.int64)
        e, a = np.nonzero(np.broadcast_to(active[:, None], (n, k)))
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                y, x = positions[e, a, 1] + dy, positions[e, a, 0] + dx
                ok = (y >= 0) & (y < h) & (x >= 0) & (x < w)
                win[e[ok], a[ok], y[ok], x[ok]] = 1
        others = (win.sum(axis=1, keepdims=True) - win) > 0  # (n, N, h, w): shown by someone else
        self.covered |= others.reshape(n * k, h, w)
        stood = np.zeros((n, k, h, w), np.int64)
        stood[e, a, positions[e, a, 1], positions[e, a, 0]] = 1
        self.trodden |= ((stood.sum(axis=1, keepdims=True) - stood) > 0).reshape(n * k, h, w)

    def _settle(self, active: np.ndarray) -> None:
        """Static targets: a cell another agent has stood on holds no unfound target (the world
        recovers a target when an agent is on its cell), so each copy moves its sighted mass on
        such cells to found, from the beacons alone. Why: a teammate's view that arrives after
        the target it shows was recovered by a third agent, whose own report was lost, would
        leave a phantom target for good: the agent flew to it, counted a find that was not one,
        and with every target believed found stopped exploring (delay 2 and 5 % loss cost 8 %
        of makespan at N = 4 before this rule, delay 2 alone 2.6 %)."""
        b = self.belief
        hit = self.trodden & (b._sighted > 0)
        if not hit.any():
            return
        u = np.where(hit, b._sighted, np.float32(0.0))
        b._sighted = b._sighted - u
        b.found = b.found + u
        cap = np.where(np.repeat(active, self.n_agents), self.cfg.n_targets - 1, self.cfg.n_targets)
        b.n_found = np.minimum(b.n_found + u.sum(axis=(1, 2), dtype=np.float64), cap)
        b.target = b._target()

    def update(self, views: np.ndarray, positions: np.ndarray, t: np.ndarray, active: np.ndarray) -> None:
        """Fold one joint step's observations: views (n, N, 3, 3, 3), positions (n, N, 2)."""
        n, k = self.n, self.n_agents
        views, positions = np.asarray(views), np.asarray(positions, np.int64)
        t, active = np.asarray(t, np.int64), np.asarray(active, bool)
        if self.shared:
            for i in range(k):
                self._fold(views[:, i], positions[:, i], t, active)
            return
        if self.covered is not None:
            self._cover(positions, active)
        self._step += 1
        self._sent.append((views.copy(), positions.copy(), active.copy()))
        c = self.comms
        keep = c.delay + c.history
        if len(self._sent) > keep:
            self._sent.pop(0)
        first = self._step - len(self._sent) + 1  # the step of self._sent[0]
        tr, ar = np.repeat(t, k), np.repeat(active, k)
        own_v, own_p = views.reshape(n * k, *views.shape[2:]), positions.reshape(n * k, 2)
        self._fold(own_v, own_p, tr, ar)  # each agent's own view, at once
        u = self._step - c.delay  # the step whose messages arrive now
        if u < 0 or (self.cfg.moving and c.delay > 0):
            # moving targets: a view of some steps ago cannot be folded into the forward filter
            # as if taken now (the targets moved on; folded so, delay 1 alone doubled the
            # random-walk makespan at N = 2, 20.3 -> 44.6 moves): the copy keeps its own views
            self._settle_static(active)
            return
        recv = np.arange(k)
        sent_then = self._sent[u - first][2]  # (n,) the senders' episodes were running
        for m in range(1, k):
            sender = (recv + m) % k  # (N,): receiver i hears from sender (i + m) % N
            got = (self.rng.random((n, k)) >= c.loss) & sent_then[:, None]  # (n, N) per receiver
            self.delivered[:, sender, recv] += got
            self.lost[:, sender, recv] += ~got & sent_then[:, None]
            last = self._last[:, sender, recv]  # (n, N)
            # the message carries the sender's observations of steps u - history + 1 .. u, oldest
            # first; a receiver folds those it has not folded yet. Rows with nothing to fold are
            # given their own view again (folding one view twice changes nothing: its cells are
            # set to the same, its find was counted the first time)
            for q in range(max(u - c.history + 1, first, 0), u + 1):
                fold = got & (q > last)
                if not fold.any():
                    continue
                qv, qp, _ = self._sent[q - first]
                v = np.where(fold[..., None, None, None], qv[:, sender], views)
                p = np.where(fold[..., None], qp[:, sender], positions)
                self._fold(v.reshape(n * k, *views.shape[2:]), p.reshape(n * k, 2), tr, ar)
            self._last[:, sender, recv] = np.where(got, u, last)
        self._settle_static(active)

    def _settle_static(self, active: np.ndarray) -> None:
        if not self.cfg.moving and self.trodden is not None:
            self._settle(active)
