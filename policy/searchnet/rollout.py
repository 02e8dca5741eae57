"""DAgger's data: the student drives (mixed with the teacher at rate beta), the teacher labels.

Every state the student reaches is labelled with the action the teacher would take there: the
teacher is a belief-space policy too, so it is run on the same observation stream and its
answer at each step is the label, whoever actually moved. One task is a chunk of episodes with
its own seed, so chunks fan out over processes or ray workers and give the same data anywhere.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

from ..base import observe
from ..belief import BeliefState
from .config import SearchNetConfig
from .model import SearchNet
from .policy import obs_tensors

N_ACTIONS = 5


@dataclass(frozen=True)
class RolloutTask:
    grid: dict
    episodes: int
    seed: int
    #: probability that the teacher's action is the one executed (per step); 1.0: pure teacher
    beta: float
    #: the student (None: no student yet, the teacher drives)
    model_cfg: dict | None = None
    state_dict: dict[str, Any] | None = None
    #: the placement prior the teacher may use ('model', an (h, w) array or a dataset path, see
    #: policy.planner.resolve_prior); never the student's
    teacher_prior: Any = None
    max_steps: int | None = None
    #: GPS noise (metres per axis) in the student's observations; 0: exact
    gps_sigma: float = 0.0
    #: one-hot level planes of the network trained (SearchNetConfig.level_planes; 0: none, 5
    #: actions); > 0: the planes gain the level flown and the actions climb and descend (7)
    level_planes: int = 0
    #: the fields (policy.searchnet.fields.FieldSpec as a dict); None: the whole grid
    fields: dict | None = None


def pad_valid(valid: np.ndarray, n_actions: int = N_ACTIONS) -> np.ndarray:
    out = np.zeros((len(valid), n_actions), dtype=bool)
    out[:, : valid.shape[1]] = valid
    return out


def collect(task: RolloutTask) -> dict[str, np.ndarray]:
    """Roll out task.episodes episodes; return the student's states with the teacher's labels:
    planes (N, C, h, w) float16, positions (N, 2) int16, valid (N, 5) bool, labels (N,) int64,
    and per episode moves and success. With level planes: C gains them and valid has 7
    columns (climb, descend); the teacher is then `belief` with levels, the altitude planner.
    With fields: each task draws its own (FieldSpec.draw), the teacher and the student's belief
    know the mask (as in evaluation: obs.mask).

    With task.gps_sigma > 0 the student sees what the GPS evaluation gives (policy.evaluation.gps:
    a Kalman-fused fix, the posterior over cells, its most likely cell as the position and
    valid moves from there); the teacher still plans from the true position, so its label is
    the move the student should make from where it really is. A label the student's own mask
    rules out is dropped by the fit."""
    from ..baselines.registry import make_policy
    from ..evaluation.gps import GpsNoise, GpsTracker

    torch.set_num_threads(1)
    from .encode import level_planes
    from .fields import FieldSpec

    cfg = GridConfig.from_dict(task.grid)
    n = task.episodes
    masks = None
    spec = FieldSpec.from_dict(task.fields)
    if spec is not None:
        cfg, masks = spec.draw(cfg, n, task.seed)
    ep = sample_episodes(cfg, n, task.seed, masks)
    lp = task.level_planes
    n_act = 7 if lp else N_ACTIONS
    world = BatchGridWorld(ep, task.seed)
    teacher = make_policy("belief", cfg, prior=task.teacher_prior)
    teacher.reset(cfg, n, task.seed)
    student = None
    if task.state_dict is not None:
        student = SearchNet(SearchNetConfig.from_dict(task.model_cfg))
        student.load_state_dict({k: torch.as_tensor(v) for k, v in task.state_dict.items()})
        student.eval()
    belief = BeliefState(cfg, n) if masks is None else BeliefState(cfg, n, mask=masks)
    rng = np.random.default_rng([task.seed, 0xDA66E5])
    limit = task.max_steps or cfg.t_e + 1
    tracker = None
    if task.gps_sigma > 0:
        if cfg.moving or cfg.map_variant != "spatial":
            raise ValueError("GPS noise in training covers static targets with the spatial map (as its evaluation)")
        tracker = GpsTracker(cfg, GpsNoise(sigma_m=task.gps_sigma), n, np.random.default_rng([task.seed, 0x6B5]))
    out: dict[str, list[np.ndarray]] = {"planes": [], "positions": [], "valid": [], "labels": []}
    for _ in range(limit):
        if world.done.all():
            break
        obs = observe(world)
        label = np.asarray(teacher.act(obs), dtype=np.int64)
        seen = obs  # what the student observes
        if tracker is not None:
            tracker.fix(world.agent.astype(np.float64), obs.active)
            seen = tracker.observation(obs.views, obs.t, obs.active)
        belief.update(seen)
        planes = belief.planes()
        if lp:
            planes = np.concatenate([planes, level_planes(obs.level, n, cfg.height, cfg.width, lp)], axis=1)
        act = obs.active
        valid = pad_valid(seen.valid, n_act)
        out["planes"].append(planes[act].astype(np.float16))
        out["positions"].append(seen.positions[act].astype(np.int16))
        out["valid"].append(valid[act])
        out["labels"].append(label[act])
        a = label.copy()
        if student is not None and task.beta < 1.0:
            with torch.inference_mode():
                x, mask = obs_tensors(planes, seen.positions, valid, n_act)
                mine = student(x, mask).argmax(dim=1).numpy()
            use_student = rng.random(n) >= task.beta
            a = np.where(use_student, mine, label)
        a = np.minimum(a, cfg.n_actions - 1)
        world.step(a)
        if tracker is not None:
            tracker.moved(a, act)
    data = {k: np.concatenate(v) for k, v in out.items()}
    data["moves"] = world.t.copy()
    data["success"] = world.success.copy()
    return data


def merge(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Concatenate tasks' data; planes of different grids (random masked fields) are padded to
    the largest at the bottom and right with zeros (off the field, as a batch of padded fields
    shows it; positions are top-left based and keep)."""
    shapes = {p["planes"].shape[-2:] for p in parts if "planes" in p}
    if len(shapes) > 1:
        h = max(s[0] for s in shapes)
        w = max(s[1] for s in shapes)
        parts = [{**p, "planes": np.pad(p["planes"], ((0, 0), (0, 0), (0, h - p["planes"].shape[2]),
                                                       (0, w - p["planes"].shape[3])))} for p in parts]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
