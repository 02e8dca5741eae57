"""Imitation of the realizable teacher with DAgger (Ross et al., 2011).

Iteration i: the executed policy is the teacher with probability beta_i = beta0 * decay**i per
step, else the current student; every visited state is labelled with the teacher's action and
added to one growing data set; the student is retrained on all of it. Iteration 0 (beta = 1)
is plain behaviour cloning; later iterations add the states the student's own mistakes lead to,
which is what lets it recover from them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from sim.gridworld import GridConfig

from ..fanout import fan_out
from .encode import egocentric
from .fields import FieldSpec
from .model import SearchNet
from .rollout import RolloutTask, collect, merge


@dataclass(frozen=True)
class DaggerConfig:
    iterations: int = 6
    #: episodes rolled out per iteration (split into `chunks` seeded tasks)
    episodes: int = 400
    chunks: int = 2
    beta0: float = 1.0
    beta_decay: float = 0.5
    epochs: int = 3
    batch: int = 256
    lr: float = 2e-3
    #: training episodes are drawn from seeds >= this, far from every test seed range
    seed_base: int = 1_000_000
    #: cap on a rollout's steps (students that wander are cut; their states are still labelled)
    max_steps_factor: float = 1.5
    #: GPS noise in the student's observations (metres per axis, cells of 2 m; 0: exact): its
    #: belief is built from a Kalman-fused position posterior on the probabilistic map, as in
    #: the GPS evaluation; the teacher labels from the true position (policy.searchnet.rollout)
    gps_sigma: float = 0.0
    #: the fields rolled out on (policy.searchnet.fields: a fixed masked field or random masked
    #: fields of some classes); None: the whole grid, as before masks
    fields: FieldSpec | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.gps_sigma) and self.gps_sigma >= 0):
            raise ValueError(f"gps_sigma must be >= 0 metres (got {self.gps_sigma})")
        if self.iterations < 0 or self.episodes < 1 or self.chunks < 1 or self.epochs < 1 or self.batch < 1:
            raise ValueError(f"DaggerConfig needs positive counts, iterations >= 0 (got {self})")
        if not (0.0 <= self.beta0 <= 1.0 and 0.0 <= self.beta_decay <= 1.0):
            raise ValueError(f"beta0 and beta_decay must be in [0, 1] (got {self.beta0}, {self.beta_decay})")

    def beta(self, i: int) -> float:
        return self.beta0 * self.beta_decay ** i

    def to_dict(self) -> dict:
        """`fields` appears only where it is used: a run without masks writes what it did before."""
        d = asdict(self)
        if self.fields is None:
            d.pop("fields")
        return d


def rollout_tasks(dc: DaggerConfig, grid: GridConfig, i: int, model: SearchNet | None,
                  teacher_prior: Any, level_planes: int = 0) -> list[RolloutTask]:
    """Iteration i's tasks; the seeds depend only on (seed_base, i, chunk), never on the worker.
    level_planes: the trained network's (its input gains the level, its actions climb/descend)."""
    beta = dc.beta(i) if model is not None else 1.0
    sd = None if model is None else {k: v.detach().cpu().numpy() for k, v in model.state_dict().items()}
    mc = None if model is None else model.cfg.to_dict()
    sizes = np.diff(np.linspace(0, dc.episodes, dc.chunks + 1).astype(int))
    steps = max(int(dc.max_steps_factor * grid.width * grid.height), 1)
    if dc.fields is not None and dc.fields.classes:  # random fields: the cap from their area
        steps = max(int(dc.max_steps_factor * dc.fields.area), 1)
    fields = None if dc.fields is None else dc.fields.to_dict()
    return [RolloutTask(grid.to_dict(), int(k), dc.seed_base + 1000 * i + j, beta, mc, sd, teacher_prior,
                        min(steps, grid.t_e + 1), dc.gps_sigma, level_planes, fields)
            for j, k in enumerate(sizes) if k > 0]


def gather(tasks: list[RolloutTask], workers: int = 1, ray_address: str | None = None) -> dict[str, np.ndarray]:
    return merge(fan_out(collect, [(t,) for t in tasks], workers=workers, ray_address=ray_address))


def fit(model: SearchNet, opt: torch.optim.Optimizer, data: dict[str, np.ndarray], epochs: int, batch: int,
        rng: np.random.Generator) -> float:
    """Cross-entropy on the teacher's labels over the whole aggregate; returns the last epoch's accuracy."""
    labels = torch.from_numpy(data["labels"].astype(np.int64))
    valid = torch.from_numpy(data["valid"])
    ok = valid[torch.arange(len(labels)), labels.clamp(max=valid.shape[1] - 1)] & (labels < valid.shape[1])
    idx_all = np.flatnonzero(ok.numpy())
    planes = torch.from_numpy(data["planes"])
    pos = torch.from_numpy(data["positions"].astype(np.int64))
    model.train()
    acc = 0.0
    for _ in range(epochs):
        order = rng.permutation(idx_all)
        hits = 0
        for s in range(0, len(order), batch):
            b = torch.from_numpy(order[s: s + batch])
            x = egocentric(planes[b].float(), pos[b])
            logits = model(x, valid[b])
            loss = F.cross_entropy(logits, labels[b])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            hits += int((logits.argmax(1) == labels[b]).sum())
        acc = hits / max(len(order), 1)
    model.eval()
    return acc


def run_dagger(model: SearchNet, grid: GridConfig, dc: DaggerConfig, teacher_prior: Any = None,
               start: int = 0, data: dict[str, np.ndarray] | None = None, opt: torch.optim.Optimizer | None = None,
               workers: int = 1, ray_address: str | None = None,
               on_iteration: Callable[[int, dict, dict[str, np.ndarray]], None] | None = None,
               student_first: bool = False) -> dict[str, np.ndarray]:
    """Iterations start .. dc.iterations - 1; `data` is the aggregate so far (resume). on_iteration(i,
    metrics, data) is called after each (the trainer checkpoints there). Returns the aggregate.
    Iteration 0 is behaviour cloning (the teacher drives) unless student_first: a student that is
    already trained (fine-tuning) drives from the start, mixed with the teacher at beta0."""
    opt = opt or torch.optim.Adam(model.parameters(), lr=dc.lr)
    rng = np.random.default_rng([dc.seed_base, 0xF17])
    for i in range(start, dc.iterations):
        drive = model if i or student_first else None
        new = gather(rollout_tasks(dc, grid, i, drive, teacher_prior, model.cfg.level_planes), workers, ray_address)
        stats = {"iteration": i, "beta": dc.beta(i) if drive is not None else 1.0, "rollout_moves": float(new["moves"].mean()),
                 "rollout_success": float(new["success"].mean()), "new_states": int(len(new["labels"]))}
        new = {k: v for k, v in new.items() if k not in ("moves", "success")}
        data = new if data is None else merge([data, new])
        stats["train_acc"] = fit(model, opt, data, dc.epochs, dc.batch, rng)
        stats["states"] = int(len(data["labels"]))
        if on_iteration is not None:
            on_iteration(i, stats, data)
    assert data is not None
    return data
