"""Table I, reproduced: every row synthesised, trained and evaluated, with the paper's
figures side by side. `small` runs on 2 CPU cores in well under 30 minutes; `full` is the
paper's protocol (20k / 60k training episodes, 50 epochs of SGD, 10 folds, 20k test episodes).

Rows run as independent jobs (local processes, or a ray cluster with --ray-address). The +S
rows render the camera view with the PyBullet scene (sim.vehicle), which is why this lives in
missions/: it is the one package allowed to wire the renderer into the policy pipeline.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open, atomic_write_json, git_revision, stamp
from sim.gridworld import GridConfig


@dataclass(frozen=True)
class Scale:
    train_static: int
    train_moving: int
    test: int
    epochs: int
    folds: int
    run_folds: int
    optimizer: str
    lr: float
    arch: str = "small"
    #: train the DRQN row's agent for this many episodes (resumable, in the row's work folder);
    #: 0: test a given checkpoint (the shipped one by default)
    drqn_episodes: int = 0


SCALES = {
    # 4000 static episodes (2000 before): on 2 cores the rows fit in < 30 min with it, and the
    # Random (PT) row measured 0.259 -> 0.267 recovery, 64.5 -> 48.8 % loops (8000: 0.271, too slow)
    "small": Scale(train_static=4000, train_moving=3000, test=1000, epochs=4, folds=5, run_folds=2,
                   optimizer="adam", lr=1e-3),
    # a minute end to end: checks the pipeline (the numbers mean nothing at this size)
    "smoke": Scale(train_static=40, train_moving=40, test=30, epochs=1, folds=2, run_folds=1,
                   optimizer="adam", lr=1e-3, drqn_episodes=16),
    "full": Scale(train_static=20000, train_moving=60000, test=20000, epochs=50, folds=10, run_folds=10,
                  optimizer="sgd", lr=1e-3, drqn_episodes=20_000),
}


@dataclass(frozen=True)
class Row:
    name: str  # the paper's row label
    kind: str  # ns | drqn | net
    grid: GridConfig
    method: str = "pt"
    model: str = "dualstream"
    rendered: bool = False


def rows() -> list[Row]:
    g = GridConfig
    return [
        Row("NS", "ns", g()),
        Row("DRQN", "drqn", g()),
        Row("SSN (PT)", "net", g(), model="ssn"),
        Row("Random (CU)", "net", g(), method="cu"),
        Row("Random (PT)", "net", g()),
        Row("Fixed Grid", "net", g(distribution="fixed")),
        Row("Equidistant", "net", g(distribution="equidistant")),
        Row("Gaussian", "net", g(distribution="gaussian")),
        Row("Random (+S)", "net", g(), rendered=True),
        Row("Random (+M)", "net", g(map_variant="memory")),
        Row("Equidistant (+M)", "net", g(distribution="equidistant", map_variant="memory")),
        Row("Gaussian (+M)", "net", g(distribution="gaussian", map_variant="memory")),
        Row("Random Walk", "net", g(motion="random_walk", map_variant="spatiotemporal")),
        Row("Herd Walk", "net", g(distribution="equidistant", motion="herd", map_variant="spatiotemporal")),
        Row("Herd Walk (+S)", "net", g(distribution="equidistant", motion="herd", map_variant="spatiotemporal"),
            rendered=True),
    ]


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")


def _renderer_view_fn(grid: GridConfig, seed: int):
    """The +S sensor: the 50x50 downward camera at 3.5 m over the agent's cell."""
    from sim.vehicle import ViewRenderer

    r = ViewRenderer(grid.width, grid.height, grid.n_targets, image=50, seed=seed)

    def view_fn(world) -> np.ndarray:
        return r.render_views(world.targets(), world.agent, grid.width, grid.height)

    return view_fn


def run_row(row: Row, scale_name: str, work: str, seed: int, drqn_checkpoint: str | None) -> dict[str, Any]:
    """One Table I row end to end; returns its columns (or why it is not there yet)."""
    import torch

    torch.set_num_threads(1)
    from policy.baselines import make_policy
    from policy.data import synthesize
    from policy.evaluation import evaluate
    from policy.nn import load_policy
    from policy.training import TrainConfig, train

    sc = SCALES[scale_name]
    d = Path(work) / _slug(row.name)
    d.mkdir(parents=True, exist_ok=True)
    (d / "eval.npz").unlink(missing_ok=True)  # a row that is "not yet" must not plot an old run
    t0 = time.perf_counter()
    info: dict[str, Any] = {"row": row.name, "grid": row.grid.to_dict(), "method": row.method, "model": row.model,
                            "rendered": row.rendered, "git_revision": git_revision()}
    view_fn = _renderer_view_fn(row.grid, seed) if row.rendered else None
    if row.kind == "ns":
        policy = make_policy("ns", row.grid)
    elif row.kind == "drqn":
        if drqn_checkpoint is None and sc.drqn_episodes:
            from policy.drqn import DrqnConfig, train_drqn

            drqn_checkpoint = str(train_drqn(DrqnConfig(episodes=sc.drqn_episodes), row.grid, d / "drqn", seed=seed,
                                             progress=False, resume=True))
        if drqn_checkpoint is None or not Path(drqn_checkpoint).exists():
            return info | {"not_yet": "no DRQN checkpoint (train one: uavsearch train --model drqn)"}
        policy = make_policy("drqn", row.grid, checkpoint=Path(drqn_checkpoint))
        info["drqn_checkpoint"] = str(drqn_checkpoint)
    else:
        n_train = sc.train_moving if row.grid.moving else sc.train_static
        ds = synthesize(row.grid, n_train, seed, d / "dataset", method=row.method, view_fn=view_fn,
                        progress=False, overwrite=True)
        tc = TrainConfig(model=row.model, arch=sc.arch, epochs=sc.epochs, folds=sc.folds, run_folds=sc.run_folds,
                         optimizer=sc.optimizer, lr=sc.lr, seed=seed, device="auto", threads=1)
        summary = train(ds, d / "run", tc, progress=False)
        info |= {"cv_acc_mean": 100 * summary["cv_acc_mean"], "cv_acc_sd": 100 * summary["cv_acc_sd"],
                 "train_samples": summary["samples"]}
        policy = load_policy(d / "run" / "model.pt", cfg=row.grid, name=_slug(row.name))
    r = evaluate(policy, row.grid, sc.test, seed + 10_000, progress=False, view_fn=view_fn)
    np.savez_compressed(d / "eval.npz", moves=r.moves, optimal=r.optimal)
    info |= r.columns | {"seconds": time.perf_counter() - t0}
    return info


def run_table1(scale: str, out: Path, seed: int = 0, only: list[str] | None = None, workers: int | None = None,
               ray_address: str | None = None, drqn_checkpoint: Path | None = None,
               work: Path | None = None) -> dict[str, Any]:
    """Datasets, runs and per-row evaluations go to `work` (default runs/table1_<scale>);
    only the table (Markdown, JSON) and the Fig. 4 plot go to `out`."""
    from policy.fanout import fan_out

    if scale not in SCALES:
        raise ValueError(f"scale must be one of {list(SCALES)}")
    todo = [r for r in rows() if only is None or r.name in only]
    if only and len(todo) != len(only):
        known = [r.name for r in rows()]
        raise ValueError(f"unknown row(s) {sorted(set(only) - set(known))}; rows: {known}")
    out.mkdir(parents=True, exist_ok=True)
    work = work or Path("runs") / f"table1_{scale}"
    work.mkdir(parents=True, exist_ok=True)
    tasks = [(r, scale, str(work), seed, None if drqn_checkpoint is None else str(drqn_checkpoint)) for r in todo]
    results = fan_out(run_row, tasks, workers=workers, ray_address=ray_address)
    previous = out / f"table1_{scale}.json"
    if only and previous.exists():  # re-running some rows: keep the others from the last run
        last = json.loads(previous.read_text())
        done = {r["row"]: {"git_revision": last["git_revision"]} | r for r in last["rows"]}
        done |= {r["row"]: r for r in results}
        results = [done[r.name] for r in rows() if r.name in done]
    doc = stamp({"scale": asdict(SCALES[scale]), "rows": [r["row"] for r in results]}, seed, rows=results)
    atomic_write_json(out / f"table1_{scale}.json", doc)
    with atomic_open(out / f"table1_{scale}.md", "w") as f:
        f.write(render_markdown(doc, scale))
    plot_differences(out, work, [r for r in rows() if r.name in doc["config"]["rows"]], scale)
    return doc


def render_markdown(doc: dict[str, Any], scale: str) -> str:
    from policy.evaluation.paper import PAPER_TABLE1
    from policy.evaluation.report import TABLE_COLUMNS, format_cell

    sc = doc["config"]["scale"]
    head = "| row | source | " + " | ".join(h for _, h, _ in TABLE_COLUMNS) + " |"
    lines = [
        f"# Table I reproduced ({scale} scale)",
        "",
        f"Training episodes: {sc['train_static']} static / {sc['train_moving']} moving; test episodes: {sc['test']}; "
        f"{sc['epochs']} epochs of {sc['optimizer']} (lr {sc['lr']}), {sc['run_folds']} of {sc['folds']} folds, "
        f"architecture `{sc['arch']}`; seed {doc['seed']}; git `{doc['git_revision']}`.",
        "",
        head,
        "|" + "---|" * (len(TABLE_COLUMNS) + 2),
    ]
    for row in doc["rows"]:
        name = row["row"]
        if "not_yet" in row:
            lines.append(f"| {name} | ours | not yet: {row['not_yet']} |" + " |" * (len(TABLE_COLUMNS) - 1))
        else:
            lines.append(f"| {name} | ours | " + " | ".join(format_cell(row, k, f) for k, _, f in TABLE_COLUMNS) + " |")
        p = PAPER_TABLE1.get(name)
        if p:
            lines.append(f"| {name} | paper | " + " | ".join(format_cell(p, k, f) for k, _, f in TABLE_COLUMNS) + " |")
    lines += ["", "Columns as defined in docs/metrics.md; (h) is held-out accuracy over the folds run."]
    other = [f"{r['row']} (`{r['git_revision']}`)" for r in doc["rows"]
             if r.get("git_revision", doc["git_revision"]) != doc["git_revision"]]
    if other:
        lines.append("Rows kept from an earlier run (`--only` re-ran the others), with their revision: "
                     + ", ".join(other) + ".")
    lines.append("")
    return "\n".join(lines)


def plot_differences(out: Path, work: Path, todo: list[Row], scale: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    bins = np.arange(-0.5, 102.5, 2)  # the last bin holds the clipped 100
    for r in todo:
        f = work / _slug(r.name) / "eval.npz"
        if r.grid.moving or not f.exists():
            continue
        z = np.load(f)
        ax.hist(np.clip(z["moves"] - z["optimal"], 0, 100), bins=bins, density=True, histtype="step", label=r.name)
    ax.set(xlabel="|S| - |S_GO| (clipped at 100)", ylabel="fraction of episodes",
           title=f"Fig. 4 reproduced: static rows, {scale} scale")
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_open(out / f"fig4_{scale}.png", "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)


__all__ = ["SCALES", "Row", "Scale", "render_markdown", "rows", "run_row", "run_table1"]
