"""DAgger for the decentralised team searchnet (issue 29): the team planner labels, the
learner drives.

Every joint step of a team rollout, the team planner (policy.team.planner.TeamBeliefPlanner:
sequential greedy claims and regions on the shared belief) is run on the same observation
stream and its move for agent i is agent i's label; the states stored are the learner's
decentralised inputs (policy.searchnet.team.team_planes: the shared belief around agent i, its
own cell, its teammates' cells). The executed joint move is the planner's with probability
beta per episode and step, else the learner's (its logits through the fixed-priority
separation, as it will fly), so later iterations add the states the learner's own mistakes lead
to. One task is a chunk of episodes with its own seed (as policy.searchnet.rollout), so the
data do not depend on where it ran.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch

from sim.gridworld import GridConfig, sample_episodes
from sim.gridworld.team import TeamGridWorld, team_starts

from ..belief.shared import SharedBelief
from ..fanout import fan_out
from ..team.base import separate, team_observe
from .config import SearchNetConfig
from .dagger import fit
from .model import SearchNet
from .rollout import merge
from .team import padded_valid, team_logits, team_planes


@dataclass(frozen=True)
class TeamDaggerConfig:
    iterations: int = 5
    #: episodes rolled out per iteration and setting (split into `chunks` seeded tasks)
    episodes: int = 100
    chunks: int = 1
    #: the planner's share of the executed joint moves in iteration i: beta0 * beta_decay ** i
    beta0: float = 0.5
    beta_decay: float = 0.5
    #: passes over the aggregate per iteration, each over at most fit_states states drawn from it
    epochs: int = 2
    fit_states: int = 40_000
    batch: int = 256
    lr: float = 1e-3
    #: training episodes are drawn from seeds >= this (the single-agent DAgger's range + 500 k),
    #: far from every test seed
    seed_base: int = 1_500_000
    #: cap on a rollout's joint steps, times h * w / N (a learner that wanders is cut)
    max_steps_factor: float = 1.5

    def __post_init__(self) -> None:
        if self.iterations < 0 or self.episodes < 1 or self.chunks < 1 or self.epochs < 1 or self.batch < 1 \
                or self.fit_states < 1:
            raise ValueError(f"TeamDaggerConfig needs positive counts (got {self})")
        if not (0.0 <= self.beta0 <= 1.0 and 0.0 <= self.beta_decay <= 1.0):
            raise ValueError(f"beta0 and beta_decay must be in [0, 1] (got {self.beta0}, {self.beta_decay})")
        if not self.lr > 0 or not self.max_steps_factor > 0:
            raise ValueError(f"lr and max_steps_factor must be > 0 (got {self.lr}, {self.max_steps_factor})")

    def beta(self, i: int) -> float:
        return self.beta0 * self.beta_decay ** i

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class TeamRolloutTask:
    grid: dict
    n_agents: int
    episodes: int
    seed: int
    #: probability that the planner's joint move is the one executed (per episode and step)
    beta: float
    model_cfg: dict | None = None
    state_dict: dict[str, Any] | None = None
    max_steps: int | None = None
    #: the trained network's teammates' planes (SearchNetConfig.team_planes)
    team_planes: int = 1


def collect_team(task: TeamRolloutTask) -> dict[str, np.ndarray]:
    """Roll out a chunk; the learner's per-agent states with the planner's labels: planes
    (M, C + 1, h, w) float16, positions (M, 2) int16, valid (M, 5) bool, labels (M,) int64,
    and per episode the makespan (moves) and success."""
    from ..team.planner import TeamBeliefPlanner

    torch.set_num_threads(1)
    cfg, k, n = GridConfig.from_dict(task.grid), task.n_agents, task.episodes
    ep = sample_episodes(cfg, n, task.seed)
    world = TeamGridWorld(ep, team_starts(ep, k), task.seed)
    teacher = TeamBeliefPlanner()
    teacher.reset(cfg, n, k, task.seed)
    shared = SharedBelief(cfg, n, k)  # the learner's: perfect sharing, one belief per episode
    rows = np.repeat(np.arange(n)[:, None], k, axis=1)
    student = None
    if task.state_dict is not None:
        student = SearchNet(SearchNetConfig.from_dict(task.model_cfg))
        student.load_state_dict({key: torch.as_tensor(v) for key, v in task.state_dict.items()})
        student.eval()
    rng = np.random.default_rng([task.seed, 0x7DA66E])
    out: dict[str, list[np.ndarray]] = {"planes": [], "positions": [], "valid": [], "labels": []}
    for _ in range(task.max_steps or cfg.t_e + 1):
        if world.done.all():
            break
        obs = team_observe(world)
        label = np.asarray(teacher.act(obs), np.int64)  # (n, N)
        shared.update(obs.views, obs.positions, obs.t, obs.active)
        planes = team_planes(shared.belief.planes(), rows, obs.positions, task.team_planes)  # (n * N, ...)
        pos = np.asarray(obs.positions, np.int64)
        valid = np.asarray(obs.valid)
        act = np.repeat(obs.active, k)
        out["planes"].append(planes[act].astype(np.float16))
        out["positions"].append(pos.reshape(n * k, 2)[act].astype(np.int16))
        out["valid"].append(padded_valid(valid.reshape(n * k, -1), 5)[act])
        out["labels"].append(label.reshape(n * k)[act])
        a = label
        if student is not None and task.beta < 1.0:
            z = team_logits(student, planes, pos.reshape(n * k, 2), valid.reshape(n * k, -1)).reshape(n, k, -1)
            mine = separate(pos, z[..., : valid.shape[-1]], valid)
            a = np.where((rng.random(n) >= task.beta)[:, None], mine, label)
        world.step(a)
    data = {key: np.concatenate(v) for key, v in out.items()}
    data["moves"] = world.t.copy()
    data["success"] = world.success.copy()
    return data


def team_tasks(dc: TeamDaggerConfig, settings: list[tuple[GridConfig, int]], i: int,
               model: SearchNet | None, team_planes: int = 1) -> list[TeamRolloutTask]:
    """Iteration i's tasks over the (grid, N) settings; seeds depend on (seed_base, i, setting,
    chunk) only."""
    beta = dc.beta(i) if model is not None else 1.0
    sd = None if model is None else {key: v.detach().cpu().numpy() for key, v in model.state_dict().items()}
    mc = None if model is None else model.cfg.to_dict()
    sizes = np.diff(np.linspace(0, dc.episodes, dc.chunks + 1).astype(int))
    tasks = []
    for s, (grid, k) in enumerate(settings):
        steps = min(max(int(dc.max_steps_factor * grid.width * grid.height / k), 1), grid.t_e + 1)
        tasks += [TeamRolloutTask(grid.to_dict(), k, int(m), dc.seed_base + 10_000 * i + 100 * s + j, beta, mc, sd,
                                  steps, team_planes) for j, m in enumerate(sizes) if m > 0]
    return tasks


def _subsample(data: dict[str, np.ndarray], m: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    n = len(data["labels"])
    if n <= m:
        return data
    idx = np.sort(rng.choice(n, m, replace=False))
    return {key: v[idx] for key, v in data.items()}


def _by_shape(data: list[dict[str, np.ndarray]]) -> list[dict[str, np.ndarray]]:
    """Group the chunks by field size (a 10 x 10 and a 20 x 20 setting are fitted apart: the
    egocentric windows differ in size, a batch must not)."""
    groups: dict[tuple[int, int], list[dict[str, np.ndarray]]] = {}
    for d in data:
        groups.setdefault(d["planes"].shape[-2:], []).append(d)
    return [merge(g) for g in groups.values()]


def run_team_dagger(model: SearchNet, settings: list[tuple[GridConfig, int]], dc: TeamDaggerConfig,
                    workers: int = 1, on_iteration: Callable[[int, dict, SearchNet], None] | None = None,
                    student_first: bool = True) -> list[dict]:
    """Iterations 0 .. dc.iterations - 1 over the (grid, N) settings, one network for all;
    on_iteration(i, stats, model) after each (the trainer validates and checkpoints there).
    student_first: the (warm-started) learner drives from iteration 0, mixed with the planner
    at beta0; else iteration 0 is behaviour cloning. Returns the per-iteration stats."""
    if not model.cfg.team_planes:
        raise ValueError("team DAgger trains a network with the teammates' plane (policy.searchnet.team.widen_for_team)")
    opt = torch.optim.Adam(model.parameters(), lr=dc.lr)
    rng = np.random.default_rng([dc.seed_base, 0x7F17])
    agg: list[dict[str, np.ndarray]] = []
    history = []
    for i in range(dc.iterations):
        drive = model if i or student_first else None
        parts = fan_out(collect_team, [(t,) for t in team_tasks(dc, settings, i, drive, model.cfg.team_planes)], workers=workers)
        stats: dict[str, Any] = {"iteration": i, "beta": dc.beta(i) if drive is not None else 1.0,
                                 "rollout_makespan": float(np.mean(np.concatenate([p["moves"] for p in parts]))),
                                 "rollout_success": float(np.mean(np.concatenate([p["success"] for p in parts]))),
                                 "new_states": int(sum(len(p["labels"]) for p in parts))}
        agg = _by_shape(agg + [{key: v for key, v in p.items() if key not in ("moves", "success")} for p in parts])
        accs = []
        for _ in range(dc.epochs):
            for group in agg:  # each field size: a pass over up to fit_states of its states
                accs.append(fit(model, opt, _subsample(group, dc.fit_states, rng), 1, dc.batch, rng))
        stats["train_acc"] = float(np.mean(accs[-len(agg):]))
        stats["states"] = int(sum(len(g["labels"]) for g in agg))
        history.append(stats)
        if on_iteration is not None:
            on_iteration(i, stats, model)
    return history
