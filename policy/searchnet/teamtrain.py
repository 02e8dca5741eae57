"""Training the decentralised team searchnet (issue 29): warm start from a single-agent
network, DAgger from the team planner, optionally MAPPO-style fine-tuning; validated on its own
seeds, the best network kept.

Run directory:
  searchnet.pt  the best network so far by validation (mean over the settings of the team
                searchnet's makespan / the team planner's on the same validation episodes),
                with provenance: settings, train config, seed, git revision, history
  history.json  one line per stage step (the start, each DAgger iteration, each MAPPO update)
Validation episodes come from VAL_SEED (the single-agent trainer's) + 500 000, far from the
training seeds and from every test seed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from provenance import atomic_write_json
from sim.gridworld import GridConfig

from ..team import evaluate_team, make_team_policy
from .checkpoint import load_searchnet, save_searchnet
from .model import SearchNet
from .team import TeamSearchNet, widen_for_team
from .teamdagger import TeamDaggerConfig, run_team_dagger
from .train import VAL_SEED

TEAM_VAL_SEED = VAL_SEED + 500_000


@dataclass(frozen=True)
class TeamTrainConfig:
    dagger: TeamDaggerConfig = field(default_factory=TeamDaggerConfig)
    #: MAPPO-style updates after DAgger (policy.searchnet.mappo; 0: imitation only)
    mappo_updates: int = 0
    mappo: dict = field(default_factory=dict)
    val_episodes: int = 100
    seed: int = 0
    #: the network's teammates' planes (policy.searchnet.team.teammates_planes): 1 their cells,
    #: 2 also the cells another agent is nearer
    team_planes: int = 1

    def __post_init__(self) -> None:
        if self.team_planes not in (1, 2):
            raise ValueError(f"TeamTrainConfig.team_planes must be 1 or 2 (got {self.team_planes})")
        if self.mappo_updates < 0 or self.val_episodes < 1:
            raise ValueError(f"TeamTrainConfig: mappo_updates >= 0, val_episodes >= 1 (got {self})")
        if self.dagger.iterations == 0 and self.mappo_updates == 0:
            raise ValueError("TeamTrainConfig: no DAgger iteration and no MAPPO update: nothing to train")

    def to_dict(self) -> dict:
        return {"dagger": self.dagger.to_dict(), "mappo_updates": self.mappo_updates, "mappo": dict(self.mappo),
                "val_episodes": self.val_episodes, "seed": self.seed, "team_planes": self.team_planes}


def validate(model: SearchNet, settings: list[tuple[GridConfig, int]], episodes: int,
             planner: list[float] | None = None) -> dict[str, Any]:
    """Team searchnet vs the team planner on the validation episodes of each (grid, N)."""
    out: dict[str, Any] = {"cells": []}
    ratios = []
    for s, (grid, k) in enumerate(settings):
        r = evaluate_team(TeamSearchNet(model), grid, episodes, TEAM_VAL_SEED, k, progress=False)
        p = planner[s] if planner else float(evaluate_team(make_team_policy("belief"), grid, episodes, TEAM_VAL_SEED,
                                                            k, progress=False).makespan.mean())
        ms = float(r.makespan.mean())
        ratios.append(ms / p)
        out["cells"].append({"grid": f"{grid.width}x{grid.height}/{grid.n_targets}", "agents": k, "makespan": ms,
                             "planner": p, "ratio": ms / p, "success": float((r.makespan <= grid.t_e).mean()),
                             "blocked": float(r.blocked.sum(axis=1).mean())})
    out["score"] = float(np.mean(ratios))
    return out


def train_team(out: Path, settings: list[tuple[GridConfig, int]], init: Path, tc: TeamTrainConfig,
               workers: int = 1, log=print) -> dict[str, Any]:
    """Train; returns the summary (best score, history). The network goes to out/searchnet.pt."""
    torch.manual_seed(tc.seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base, _ = load_searchnet(init)
    model = widen_for_team(base, tc.team_planes)
    if model.cfg.team_planes != tc.team_planes:
        raise ValueError(f"{init}: a team network with {model.cfg.team_planes} teammates' plane(s), the run asks "
                         f"for {tc.team_planes}")
    history: list[dict] = []
    t0 = time.perf_counter()
    val = validate(model, settings, tc.val_episodes)
    planner = [c["planner"] for c in val["cells"]]
    best = {"score": val["score"], "stage": "init", "val": val}
    grids = [{"grid": g.to_dict(), "agents": k} for g, k in settings]

    def record(stage: str, stats: dict, model: SearchNet) -> None:
        v = validate(model, settings, tc.val_episodes, planner)
        line = {"stage": stage, **stats, "val": v, "seconds": round(time.perf_counter() - t0, 1)}
        history.append(line)
        log(f"{stage} {stats.get('iteration', stats.get('update', ''))}: val score {v['score']:.4f} "
            + " ".join(f"{c['grid']} x{c['agents']} {c['makespan']:.2f}/{c['planner']:.2f}" for c in v["cells"])
            + f" ({line['seconds']} s)")
        if v["score"] < best["score"]:
            best.update(score=v["score"], stage=f"{stage} {stats.get('iteration', stats.get('update'))}", val=v)
            save_searchnet(out / "searchnet.pt", model, settings=grids, train=tc.to_dict(), seed=tc.seed,
                           init=str(init), stage=best["stage"], metrics=v)
        atomic_write_json(out / "history.json", {"settings": grids, "train": tc.to_dict(), "init": str(init),
                                                 "init_val": val, "history": history, "best": best})

    history.append({"stage": "init", "val": val})
    log(f"init: val score {val['score']:.4f} " + " ".join(
        f"{c['grid']} x{c['agents']} {c['makespan']:.2f}/{c['planner']:.2f}" for c in val["cells"]))
    save_searchnet(out / "searchnet.pt", model, settings=grids, train=tc.to_dict(), seed=tc.seed, init=str(init),
                   stage="init", metrics=val)
    if tc.dagger.iterations:
        run_team_dagger(model, settings, tc.dagger, workers, lambda i, s, m: record("dagger", s, m))
    if tc.mappo_updates:
        from .mappo import MappoConfig, run_mappo

        best_model, _ = load_searchnet(out / "searchnet.pt")
        run_mappo(best_model, settings, MappoConfig(updates=tc.mappo_updates, **tc.mappo),
                  lambda u, s, m: record("mappo", s, m))
    return {"best": best, "history": history}
