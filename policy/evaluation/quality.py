"""Search quality (issue 11): every policy on every placement and motion, plus the GPS table.

One function builds the whole document (`run_quality`), one writes it (`write_quality`):
results/search_quality.md + .json + plots, with provenance (config, seeds, git revision).

Seeds. Every setting's test episodes are drawn by `sample_episodes(cfg, episodes, seed)` with
the test seed (default 0, the `eval` default). No training touches it: the searchnet helper's
DAgger episodes use seeds >= 1_000_000, its PPO >= 2_000_000, its validation 3_000_000; the
belief planner's weights were tuned on seeds 777 and 4242; datasets from `synth` draw their
chunks from hashed 62-bit seeds.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig

from .gps import GpsNoise, evaluate_gps
from .runner import EvalResult, evaluate

#: the table's settings: (label, GridConfig)
SETTINGS: tuple[tuple[str, GridConfig], ...] = (
    ("random", GridConfig()),
    ("gaussian", GridConfig(distribution="gaussian")),
    ("equidistant", GridConfig(distribution="equidistant")),
    ("fixed grid", GridConfig(distribution="fixed")),
    ("random walk", GridConfig(motion="random_walk", map_variant="spatiotemporal")),
    ("herd", GridConfig(distribution="equidistant", motion="herd", map_variant="spatiotemporal")),
    ("random 20x20/10", GridConfig(width=20, height=20, n_targets=10)),
)
#: row label -> (registered policy, factory kwargs)
POLICIES: dict[str, tuple[str, dict[str, Any]]] = {
    "oracle": ("oracle", {}),
    "cu": ("cu", {}),
    "ns": ("ns", {}),
    "frontier": ("frontier", {}),
    "lawnmower": ("lawnmower", {}),
    "dualstream": ("dualstream", {}),
    "belief": ("belief", {}),
    "belief+prior": ("belief", {"prior": "model"}),
    "searchnet": ("searchnet", {}),
}
GPS_SIGMAS: tuple[float, ...] = (0.0, 0.5, 1.0, 2.0)
GPS_ESTIMATORS: tuple[str, ...] = ("kalman", "fix")


@dataclass(frozen=True)
class QualityConfig:
    episodes: int = 2000
    seed: int = 0
    gps_episodes: int = 500
    policies: tuple[str, ...] = tuple(POLICIES)
    settings: tuple[str, ...] = tuple(label for label, _ in SETTINGS)
    gps: bool = True
    #: altitude levels for every setting (docs/altitude.md); 1 = the paper's single height
    levels: int = 1
    #: a detection table JSON path for levels > 1 (None: the measured default)
    detection: str | None = None
    #: every setting's move limit (None: the setting's own, 300)
    t_e: int | None = None

    def __post_init__(self) -> None:
        setting_config("random", self.levels, self.detection, self.t_e)  # a bad table fails here
        if self.episodes < 1 or self.gps_episodes < 1:
            raise ValueError(f"episodes and gps_episodes must be >= 1 (got {self.episodes}, {self.gps_episodes})")
        unknown = [p for p in self.policies if p not in POLICIES]
        if unknown:
            raise ValueError(f"unknown quality row(s) {unknown}; known: {', '.join(POLICIES)}")
        known = [label for label, _ in SETTINGS]
        bad = [s for s in self.settings if s not in known]
        if bad:
            raise ValueError(f"unknown setting(s) {bad}; known: {', '.join(known)}")


def setting_config(label: str, levels: int = 1, detection: str | None = None,
                   t_e: int | None = None) -> GridConfig:
    """The setting's GridConfig with the quality run's levels, detection table and t_e."""
    from sim.gridworld import DetectionTable

    cfg = dict(SETTINGS)[label]
    if levels == 1 and detection is None and t_e is None:
        return cfg
    table = DetectionTable.load(detection) if detection is not None else None
    return dataclasses.replace(cfg, levels=levels, detection=table, t_e=cfg.t_e if t_e is None else t_e)


def _summary(r: EvalResult) -> dict[str, Any]:
    c = r.columns
    return {
        "mean_moves": c["mean_moves"],
        "p90_moves": float(np.percentile(r.moves, 90)),
        "all_found_pct": c["success_pct"],
        "recovery_rate_mean": c["recovery_rate_mean"],
        "recovery_rate_sd": c["recovery_rate_sd"],
        "mean_optimal_moves": c["mean_optimal_moves"],
        "mean_flight_s": c.get("mean_flight_s"),
        "episodes": len(r.moves),
    }


def _make(row: str, cfg: GridConfig):
    from ..baselines import known_policies, make_policy

    name, kw = POLICIES[row]
    if name not in known_policies():
        raise LookupError(f"{name} is not registered in this checkout")
    return make_policy(name, cfg, **kw)


_ROOT = str(Path(__file__).resolve().parent.parent.parent) + "/"


def _note(e: BaseException) -> str:
    return str(e).replace(_ROOT, "")  # paths relative to the checkout


def quality_task(row: str, label: str, episodes: int, seed: int, levels: int = 1,
                 detection: str | None = None, t_e: int | None = None) -> dict[str, Any]:
    """One (policy row, setting) cell: its summary, or a note saying why it does not apply.
    A module-level function of plain arguments, so fan_out can ship it to a process or ray."""
    cfg = setting_config(label, levels, detection, t_e)
    t0 = time.perf_counter()
    try:
        pol = _make(row, cfg)
    except LookupError as e:
        return {"note": _note(e)}
    except (ValueError, FileNotFoundError) as e:  # e.g. a checkpoint for another grid or motion
        return {"note": f"not applicable: {_note(e)}"}
    # with levels the networks meet a view they were not built for (a W x W window of
    # detections): whatever they raise then says the row does not apply, not that the run failed
    errors: tuple[type[BaseException], ...] = (ValueError,) if levels == 1 else (ValueError, RuntimeError,
                                                                                 IndexError, KeyError)
    try:
        r = evaluate(pol, cfg, episodes, seed, progress=False)
    except errors as e:  # e.g. CU is defined for static targets only
        return {"note": f"not applicable: {_note(e)}"}
    return _summary(r) | {"seconds": round(time.perf_counter() - t0, 1)}


def gps_task(row: str, sigma: float, prob_map: bool, estimator: str, episodes: int, seed: int,
             checkpoint: str | None = None) -> dict[str, Any]:
    cfg = GridConfig()
    try:
        if checkpoint is None:
            pol = _make(row, cfg)
        else:
            from ..baselines import make_policy

            pol = make_policy(row, cfg, checkpoint=checkpoint)
    except (LookupError, ValueError, FileNotFoundError) as e:
        return {"note": _note(e)}
    noise = GpsNoise(sigma_m=sigma, prob_map=prob_map, estimator=estimator)
    r = evaluate_gps(pol, cfg, episodes, seed, noise, progress=False)
    return {"mean_moves": float(r.moves.mean()), "all_found_pct": r.columns["success_pct"]}


def gps_rows(policies: tuple[str, ...]) -> list[tuple[str, str, str | None]]:
    """(row label, registered policy, checkpoint) for the GPS table: belief, dualstream, and
    searchnet with each shipped searchnet checkpoint trained with or without position noise."""
    from ..baselines import known_policies

    rows: list[tuple[str, str, str | None]] = []
    for label in ("belief", "dualstream", "searchnet"):
        if label in policies and POLICIES[label][0] in known_policies():
            rows.append((label, POLICIES[label][0], None))
    if "searchnet" in known_policies() and "searchnet" in policies:
        ckdir = Path(__file__).resolve().parent.parent / "checkpoints"
        for ck in sorted(ckdir.glob("searchnet*.pt")):
            if any(k in ck.stem for k in ("gps", "noise")):
                rows.append((f"searchnet ({ck.stem})", "searchnet", str(ck)))
    return rows


def _reusable(prev: dict[str, Any] | None, qc: QualityConfig,
              refresh: tuple[str, ...] = ()) -> tuple[dict, dict]:
    """The measured cells of a previous document made with the same episodes and seed, less
    the rows named in refresh."""
    if not prev or prev.get("test_seed") != qc.seed:
        return {}, {}
    pq = prev.get("config", {}).get("quality", {})
    if (pq.get("levels", 1), pq.get("detection"), pq.get("t_e")) != (qc.levels, qc.detection, qc.t_e):
        return {}, {}  # cells measured at other heights or limits
    table = prev.get("table", {}) if prev.get("episodes") == qc.episodes else {}
    gps = prev.get("gps", {}) if prev.get("gps_episodes") == qc.gps_episodes else {}
    rev = prev.get("git_revision", "unknown")
    t = {(label, row): c | {"reused_from": c.get("reused_from", rev)}
         for label, rows in table.items() for row, c in rows.items()
         if c and "mean_moves" in c and row not in refresh}
    g = {(label, key): c | {"reused_from": c.get("reused_from", rev)}
         for label, cells in gps.items() for key, c in cells.items()
         if c and "mean_moves" in c and label.split(" ")[0] not in refresh}
    return t, g


def run_quality(qc: QualityConfig, workers: int | None = 1, ray_address: str | None = None,
                progress: bool = True, reuse: dict[str, Any] | None = None,
                refresh: tuple[str, ...] = (),
                fan: Callable[..., list[Any]] | None = None) -> dict[str, Any]:
    """Every (row, setting) cell and the GPS table, fanned out over local processes or ray.
    reuse: a previous document; its measured cells (same episodes and seed) are kept, marked
    with the revision they were measured at, and only the others (e.g. a policy that was not
    registered or had no checkpoint then) are run, and the rows named in refresh."""
    from ..fanout import fan_out

    fan = fan or fan_out
    old_t, old_g = _reusable(reuse, qc, refresh)
    table: dict[str, dict[str, Any]] = {label: {} for label in qc.settings}
    gps: dict[str, dict[str, Any]] = {}
    work: list[tuple[Callable[..., Any], tuple]] = []
    slots: list[tuple[dict, str]] = []
    for label in qc.settings:
        for row in qc.policies:
            table[label][row] = old_t.get((label, row))
            if table[label][row] is None:
                work.append((quality_task, (row, label, qc.episodes, qc.seed, qc.levels, qc.detection, qc.t_e)))
                slots.append((table[label], row))
    if qc.gps and qc.levels == 1:  # the GPS table is the single-height world's
        for label, name, ck in gps_rows(qc.policies):
            cells = gps.setdefault(label, {})
            for est in GPS_ESTIMATORS:
                for prob in (False, True):
                    for s in GPS_SIGMAS:
                        if s == 0 and (prob or est != GPS_ESTIMATORS[0]):
                            continue  # noise-free is one number per row
                        key = f"{est}/{'probabilistic' if prob else 'hard'}/{s}"
                        cells[key] = old_g.get((label, key))
                        if cells[key] is None:
                            work.append((gps_task, (name, s, prob, est, qc.gps_episodes, qc.seed, ck)))
                            slots.append((cells, key))
    t0 = time.perf_counter()
    bar = tqdm(total=len(work), desc="quality", unit="cell", disable=not progress)
    # one fan-out per chunk keeps the bar moving without giving up the parallelism
    step = max(1, (workers or 1) * 2) if not ray_address else max(1, len(work))
    for i in range(0, len(work), step):
        chunk = work[i : i + step]
        done = fan(_run_one, chunk, workers=workers, ray_address=ray_address)
        for (where, key), cell in zip(slots[i : i + step], done, strict=True):
            where[key] = cell
        bar.update(len(chunk))
    bar.close()
    cfgs = {label: setting_config(label, qc.levels, qc.detection, qc.t_e).to_dict()
            for label, _ in SETTINGS if label in qc.settings}
    return stamp(
        {"quality": dataclasses.asdict(qc), "settings": cfgs}, qc.seed,
        test_seed=qc.seed, episodes=qc.episodes, gps_episodes=qc.gps_episodes,
        gps_cell_m=GpsNoise().cell_m, gps_process_m=GpsNoise().process_m,
        table=table, gps=gps, seconds=round(time.perf_counter() - t0, 1), cells_run=len(work),
    )


def _run_one(fn: Callable[..., Any], args: tuple) -> Any:
    return fn(*args)


# ------------------------------------------------------------------------------ report
def _ratio(cell: dict[str, Any], oracle: dict[str, Any] | None) -> str:
    if not oracle or "mean_moves" not in oracle or "mean_moves" not in cell:
        return "-"
    return f"{cell['mean_moves'] / oracle['mean_moves']:.2f}"


def _reuse_note(doc: dict[str, Any]) -> str:
    revs = {c["reused_from"] for rows in doc["table"].values() for c in rows.values() if c and "reused_from" in c}
    revs |= {c["reused_from"] for cells in doc["gps"].values() for c in cells.values() if c and "reused_from" in c}
    return f" (the other cells reused from the run at {', '.join(sorted(revs))}: `--reuse`)" if revs else ""


def markdown(doc: dict[str, Any]) -> str:
    qc = doc["config"]["quality"]
    lines = [
        "# Search quality (issue 11)",
        "",
        f"`uavsearch quality --episodes {doc['episodes']}`: {doc['episodes']} test episodes per setting, "
        f"test seed {doc['test_seed']} (never used in training: searchnet trains on seeds >= 1,000,000, "
        "the belief planner was tuned on seeds 777 and 4242). Every policy meets the same episodes. "
        f"git `{doc['git_revision']}`, {doc['created_utc']}, {doc['seconds']} s for "
        f"{doc.get('cells_run', '?')} cells" + _reuse_note(doc) + ".",
        "",
        *([f"Altitude levels L = {qc['levels']} (docs/altitude.md), detection table "
           f"{qc.get('detection') or 'the measured default'}, t_e {qc.get('t_e') or 300}.", ""]
          if qc.get("levels", 1) > 1 else []),
        "Columns: mean moves; ratio of mean moves to the oracle's and to the dual-stream network's (the "
        "paper's; issue 11's moving-target goal is searchnet <= 0.6 of it); 90th percentile of moves; "
        "episodes with every target found (t_e = 300); Table I's (g) recovery rate (mean ± sd). "
        "`belief` starts from a uniform prior, `belief+prior` is given the placement model "
        "(density and pair correlation, sampled from the config). The oracle knows every target "
        "(optimal PT by Held-Karp; lookahead PT for moving targets).",
        "",
    ]
    notes: list[str] = []
    for label in qc["settings"]:
        row_cells = doc["table"][label]
        oracle, dual = row_cells.get("oracle"), row_cells.get("dualstream")
        lines += [f"## {label}", "",
                  "| policy | mean moves | / oracle | / dualstream | p90 moves | all found % | (g) recovery rate |",
                  "|---|---|---|---|---|---|---|"]
        for row in qc["policies"]:
            c = row_cells.get(row, {})
            if "mean_moves" not in c:
                notes.append(f"- {label}, {row}: {c.get('note', 'not run')}")
                continue
            lines.append(
                f"| {row} | {c['mean_moves']:.1f} | {_ratio(c, oracle)} | {_ratio(c, dual)} | {c['p90_moves']:.0f} | "
                f"{c['all_found_pct']:.1f} | {c['recovery_rate_mean']:.3f}±{c['recovery_rate_sd']:.3f} |"
            )
        lines.append("")
    big = doc["table"].get("random 20x20/10", {}).get("oracle") or {}
    if "seconds" in big:
        lines += [f"The oracle on random 20x20/10 is exact (Held-Karp over 10 targets, 2^10 x 10 "
                  f"states per episode): {big['seconds']} s for {big['episodes']} episodes, tractable.", ""]
    if notes:
        lines += ["## Cells not run", "", "The dual-stream row uses the network shipped for the setting "
                  "(policy/checkpoints/dualstream_<motion>_<distribution>.pt: the moving-target ones are Table I's "
                  "small-scale rows), else the paper's 10 x 10 static-random one.", "",
                  *notes, ""]
    if doc["gps"]:
        lines += [
            "## GPS noise (random 10x10, 5 static targets)",
            "",
            f"{doc['gps_episodes']} test episodes per cell (seed {doc['test_seed']}); sigma per axis "
            f"in metres, cells {doc['gps_cell_m']} m. Estimators: `kalman` fuses each fix with the "
            f"commanded move (process noise {doc['gps_process_m']} m per move, like the flight's "
            "estimator), `fix` uses each fix alone. Hard map: the most likely cell taken as exact; "
            "probabilistic: the posterior over cells (obs.position_prob) and the expected map M. "
            "The camera view is always the truth around the true cell.",
            "",
            "| policy | estimator | map | " + " | ".join(f"sigma {s} m" for s in GPS_SIGMAS) + " |",
            "|---|---|---|" + "---|" * len(GPS_SIGMAS),
        ]
        for label, cells in doc["gps"].items():
            free = cells.get(f"{GPS_ESTIMATORS[0]}/hard/0.0", {})
            for est in GPS_ESTIMATORS:
                for kind in ("hard", "probabilistic"):
                    vals = []
                    for s in GPS_SIGMAS:
                        c = free if s == 0 else cells.get(f"{est}/{kind}/{s}", {})
                        if "mean_moves" in c:
                            vals.append(f"{c['mean_moves']:.1f}" + ("" if c["all_found_pct"] == 100 else f" ({c['all_found_pct']:.1f} % found)"))
                        else:
                            vals.append("-")
                    if any(v != "-" for v in vals):
                        lines.append(f"| {label} | {est} | {kind} | " + " | ".join(vals) + " |")
        gps_notes = sorted({f"- {label}: {c['note']}" for label, cells in doc["gps"].items()
                            for c in cells.values() if c and "note" in c})
        if gps_notes:
            lines += ["", "GPS cells not run:", "", *gps_notes]
        lines.append("")
    lines += ["Plots: `search_quality.png` (mean moves / oracle per setting), `search_quality_gps.png`.", ""]
    return "\n".join(lines)


def plot(doc: dict[str, Any], out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    qc = doc["config"]["quality"]
    paths = []
    fig, ax = plt.subplots(figsize=(11, 4.2))
    rows = [r for r in qc["policies"] if r != "oracle"]
    labels = qc["settings"]
    width = 0.8 / max(1, len(rows))
    for k, row in enumerate(rows):
        ys = []
        for label in labels:
            c, o = doc["table"][label].get(row, {}), doc["table"][label].get("oracle", {})
            ys.append(c["mean_moves"] / o["mean_moves"] if "mean_moves" in c and "mean_moves" in o else np.nan)
        ax.bar(np.arange(len(labels)) + k * width, ys, width, label=row)
    ax.axhline(1.0, color="k", linewidth=0.8)
    ax.set_xticks(np.arange(len(labels)) + 0.4 - width / 2, labels, fontsize=8)
    ax.set_ylabel("mean moves / oracle")
    ax.set_yscale("log")
    ax.set_title(f"Search quality, {doc['episodes']} test episodes per setting")
    ax.legend(fontsize=7, ncol=4)
    fig.tight_layout()
    p = out / "search_quality.png"
    with atomic_open(p, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    paths.append(p)
    if doc["gps"]:
        fig, ax = plt.subplots(figsize=(7, 4))
        for label, cells in doc["gps"].items():
            free = cells.get(f"{GPS_ESTIMATORS[0]}/hard/0.0", {}).get("mean_moves", np.nan)
            for est in GPS_ESTIMATORS:
                for kind, style in (("hard", "--"), ("probabilistic", "-")):
                    ys = [free if s == 0 else cells.get(f"{est}/{kind}/{s}", {}).get("mean_moves", np.nan)
                          for s in GPS_SIGMAS]
                    ax.plot(GPS_SIGMAS, ys, style, marker="o" if est == "kalman" else "x",
                            label=f"{label} {est} {kind}")
        ax.set_xlabel("GPS sigma per axis (m)")
        ax.set_ylabel("mean moves")
        ax.set_yscale("log")
        ax.legend(fontsize=6)
        fig.tight_layout()
        p = out / "search_quality_gps.png"
        with atomic_open(p, "wb") as f:
            fig.savefig(f, format="png", dpi=110)
        plt.close(fig)
        paths.append(p)
    return paths


def write_quality(doc: dict[str, Any], out: Path) -> list[Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "search_quality.json", doc)
    with atomic_open(out / "search_quality.md", "w") as f:
        f.write(markdown(doc))
    return [out / "search_quality.md", out / "search_quality.json", *plot(doc, out)]
