"""Training a search network end to end, resumable: DAgger on the belief teacher, then PPO.

Run directory:
  state.pt        everything to resume (stage, iteration, weights, optimisers, critic, history)
  dagger_data.npz the aggregated DAgger data set (the states the student met, teacher labels)
  searchnet.pt    the best network so far by validation mean moves (what is shipped), with
                  provenance: grid, train config, seed, git revision, metrics
  history.json    one line per DAgger iteration and PPO update
Every file is written to a temporary name and renamed, so an interrupted run resumes from the
last finished iteration or update. Validation episodes come from their own seed range, far from
the training seeds and from every test seed range.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from provenance import atomic_write_bytes, atomic_write_json, git_revision
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

from ..base import observe
from ..belief import BELIEF_CHANNELS
from ..nn.checkpoint import CheckpointError
from .checkpoint import load_searchnet, read_searchnet, save_searchnet
from .config import SearchNetConfig
from .dagger import DaggerConfig, run_dagger
from .fields import FieldSpec
from .model import SearchNet
from .policy import SearchNetPolicy
from .ppo import PpoConfig, run_ppo

VAL_SEED = 3_000_000


@dataclass(frozen=True)
class SearchTrainConfig:
    dagger: DaggerConfig = field(default_factory=DaggerConfig)
    ppo: PpoConfig = field(default_factory=PpoConfig)
    #: PPO updates to run after DAgger (0: imitation only)
    ppo_updates: int = 20
    conv1: int = 16
    conv2: int = 32
    hidden: int = 64
    seed: int = 0
    #: the teacher plans with the placement prior and pair correlation counted from sampled
    #: episodes of the placement model ('model'; None: uniform). The student never gets it.
    teacher_prior: str | None = "model"
    val_episodes: int = 400
    #: validate every this many PPO updates
    val_every: int = 2
    #: start the actor from this searchnet checkpoint (fine-tuning: more DAgger, PPO) instead of
    #: random weights; its validation is the mark the run must beat to replace searchnet.pt
    init: str | None = None
    #: one-hot level planes of the network (SearchNetConfig.level_planes); 0: one height, 5
    #: actions (today's); > 0: the level is an input and climb/descend are actions. A grid with
    #: levels > 1 needs it >= its levels (`train` sets 3, the most GridConfig allows)
    level_planes: int = 0

    def __post_init__(self) -> None:
        if (self.level_planes or self.dagger.fields is not None) and self.ppo_updates:
            raise ValueError("SearchTrainConfig: PPO is built for one height on the whole rectangle; with "
                             "levels or masked fields train by DAgger only (ppo_updates 0)")
        if self.ppo_updates < 0 or self.val_episodes < 1 or self.val_every < 1:
            raise ValueError(f"SearchTrainConfig: ppo_updates >= 0, val_episodes >= 1, val_every >= 1 (got {self})")
        if self.dagger.iterations == 0 and self.init is None:
            raise ValueError("SearchTrainConfig: 0 DAgger iterations only when fine-tuning (give init)")

    def to_dict(self) -> dict:
        """The new options appear only where they are used: a run without levels and masks writes
        (and resumes against) the document it did before them."""
        d = {**asdict(self), "dagger": self.dagger.to_dict()}
        if not self.level_planes:
            d.pop("level_planes")
        return d

    def net(self) -> SearchNetConfig:
        if self.level_planes:
            return SearchNetConfig(BELIEF_CHANNELS, conv1=self.conv1, conv2=self.conv2, hidden=self.hidden,
                                   n_actions=7, level_planes=self.level_planes)
        return SearchNetConfig(BELIEF_CHANNELS, conv1=self.conv1, conv2=self.conv2, hidden=self.hidden)


def validate(model: SearchNet, grid: GridConfig, episodes: int, seed: int = VAL_SEED,
             fields: FieldSpec | None = None) -> dict[str, float]:
    """Mean moves and all-found rate of the greedy network on validation episodes (on fields
    drawn from the validation seed where the run trains on masked fields)."""
    pol = SearchNetPolicy(model)
    masks = None
    if fields is not None:
        grid, masks = fields.draw(grid, episodes, seed)
    ep = sample_episodes(grid, episodes, seed, masks)
    pol.reset(grid, episodes, seed)
    world = BatchGridWorld(ep, seed)
    while not world.done.all():
        world.step(pol.act(observe(world)))
    return {"val_moves": float(world.t.mean()), "val_success": float(world.success.mean())}


def _tensor_tree(sd: dict) -> dict:
    return {k: v.detach().clone() for k, v in sd.items()}


def _fixed_part(train: dict) -> dict:
    """A training config less what a resumed run may extend (DAgger iterations, PPO updates)."""
    return {**train, "ppo_updates": None, "dagger": {**train["dagger"], "iterations": None}}


def train_searchnet(grid: GridConfig, out: str | Path, tc: SearchTrainConfig, resume: bool = False,
                    workers: int = 1, ray_address: str | None = None,
                    log: Callable[[str], None] = print) -> Path:
    """Train (or resume) in `out`; returns the path of the best network (out/searchnet.pt). A
    resumed run may be given more DAgger iterations (before PPO has started) or more PPO updates."""
    out = Path(out)
    state_path, data_path, best_path = out / "state.pt", out / "dagger_data.npz", out / "searchnet.pt"
    if state_path.exists() and not resume:
        raise CheckpointError(f"{out} holds a run already: give --resume to continue it, or another --out")
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(tc.seed)
    actor = SearchNet(tc.net())
    critic = SearchNet(SearchNetConfig(BELIEF_CHANNELS, privileged_channels=1, conv1=tc.conv1, conv2=tc.conv2,
                                       hidden=tc.hidden, n_actions=actor.cfg.n_actions,
                                       level_planes=tc.level_planes))
    if grid.levels > max(tc.level_planes, 1):
        raise CheckpointError(f"the grid has {grid.levels} levels: the network needs level_planes >= {grid.levels} "
                              f"(got {tc.level_planes})")
    if tc.init is not None:
        init_net, _ = load_searchnet(tc.init)
        if init_net.cfg != actor.cfg:
            raise CheckpointError(f"{tc.init}: network {init_net.cfg} differs from this run's {actor.cfg} "
                                  "(give the same --conv/--hidden sizes)")
        actor.load_state_dict(init_net.state_dict())
    opt_d = torch.optim.Adam(actor.parameters(), lr=tc.dagger.lr)
    opt_a = torch.optim.Adam(actor.parameters(), lr=tc.ppo.lr)
    opt_c = torch.optim.Adam(critic.parameters(), lr=tc.ppo.critic_lr)
    st: dict = {"stage": "dagger", "next": 0, "history": [], "best": None, "seconds": 0.0,
                "git_revision": git_revision()}
    data = None
    if state_path.exists():
        doc = read_searchnet(state_path)
        started = {"init": None, **(doc.get("train") or {})}  # runs from before `init` existed
        if isinstance(started.get("dagger"), dict):  # ... and before gps_sigma
            started["dagger"] = {"gps_sigma": 0.0, **started["dagger"]}
        if doc.get("grid") != grid.to_dict() or _fixed_part(started) != _fixed_part(tc.to_dict()):
            raise CheckpointError(f"{state_path}: was started with another grid or training config; "
                                  f"use the same options to resume (found {doc.get('grid')}, {doc.get('train')})")
        more_dagger = tc.dagger.iterations - started["dagger"]["iterations"]
        more_ppo = tc.ppo_updates - started["ppo_updates"]
        ppo_ran = sum(h.get("stage") == "ppo" for h in doc["history"])
        if more_dagger < 0 or more_ppo < 0 or (more_dagger > 0 and ppo_ran):
            raise CheckpointError(f"{state_path}: a resumed run can only be extended (more DAgger iterations "
                                  f"before any PPO update, more PPO updates); it was started with "
                                  f"{started['dagger']['iterations']} iterations and {started['ppo_updates']} updates")
        actor.load_state_dict(doc["state_dict"])
        critic.load_state_dict(doc["critic"])
        opt_d.load_state_dict(doc["opt_dagger"])
        opt_a.load_state_dict(doc["opt_actor"])
        opt_c.load_state_dict(doc["opt_critic"])
        st = {k: doc[k] for k in st}
        if data_path.exists():
            with np.load(data_path) as z:
                data = {k: z[k] for k in z.files}
        if more_dagger > 0 and st["stage"] != "dagger":  # extend: back to the DAgger loop
            st["stage"], st["next"] = "dagger", started["dagger"]["iterations"]
        elif more_ppo > 0 and st["stage"] == "done":  # extend: more PPO updates after the last one
            st["stage"], st["next"] = "ppo", ppo_ran
        log(f"resuming {out}: stage {st['stage']}, step {st['next']}")
    prior = tc.teacher_prior
    t0 = time.monotonic() - st["seconds"]

    def save_state() -> None:
        st["seconds"] = time.monotonic() - t0
        save_searchnet(state_path, actor, grid=grid.to_dict(), train=tc.to_dict(), seed=tc.seed,
                       critic=_tensor_tree(critic.state_dict()), opt_dagger=opt_d.state_dict(),
                       opt_actor=opt_a.state_dict(), opt_critic=opt_c.state_dict(), **st)
        atomic_write_json(out / "history.json", st["history"])

    def consider(metrics: dict) -> None:
        """Validate; keep the network as searchnet.pt when it is the best so far."""
        v = validate(actor, grid, tc.val_episodes, fields=tc.dagger.fields)
        metrics.update(v)
        key = (-v["val_success"], v["val_moves"])
        if st["best"] is None or key < tuple(st["best"]["key"]):
            st["best"] = {"key": list(key), **metrics}
            save_searchnet(best_path, actor, grid=grid.to_dict(), train=tc.to_dict(), seed=tc.seed,
                           metrics=dict(metrics), git_revision=st["git_revision"],
                           train_seconds=time.monotonic() - t0)

    if st["stage"] == "dagger" and st["next"] == 0 and tc.init is not None and st["best"] is None:
        consider({"stage": "init", "init": tc.init})  # the mark to beat
        save_state()
    if st["stage"] == "dagger" and tc.dagger.iterations == 0:
        st["stage"], st["next"] = "ppo", 0
        save_state()
    if st["stage"] == "dagger":
        def on_iteration(i: int, stats: dict, agg: dict[str, np.ndarray]) -> None:
            if i == tc.dagger.iterations - 1:
                consider(stats)
            st["history"].append({"stage": "dagger", **stats})
            st["next"] = i + 1
            buf = io.BytesIO()
            np.savez(buf, **agg)
            atomic_write_bytes(data_path, buf.getvalue())
            save_state()
            log(f"dagger {i}: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                            for k, v in stats.items()))

        run_dagger(actor, grid, tc.dagger, prior, start=st["next"], data=data, opt=opt_d, workers=workers,
                   ray_address=ray_address, on_iteration=on_iteration, student_first=tc.init is not None)
        st["stage"], st["next"] = "ppo", 0
        save_state()
    if st["stage"] == "ppo" and tc.ppo_updates:
        cap = tc.ppo.max_steps or min(int(1.5 * grid.width * grid.height), grid.t_e + 1)
        pc = PpoConfig(**{**tc.ppo.to_dict(), "updates": tc.ppo_updates, "max_steps": cap})

        def on_update(u: int, stats: dict) -> None:
            if (u + 1) % tc.val_every == 0 or u == pc.updates - 1:
                consider(stats)
            st["history"].append({"stage": "ppo", **stats})
            st["next"] = u + 1
            save_state()
            log(f"ppo {u}: " + ", ".join(f"{k} {v:.4g}" for k, v in stats.items()))

        run_ppo(actor, critic, grid, pc, start=st["next"], opt_a=opt_a, opt_c=opt_c, on_update=on_update)
    st["stage"] = "done"
    save_state()
    log(f"{best_path}: best {st['best']} after {st['seconds']:.0f} s")
    return best_path
