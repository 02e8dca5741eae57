"""Search from any height (issue 27): policies with altitude levels against today's single
height on the same episodes; results/altitude/*.md + .json.

Every row of a setting meets the same episodes: `sample_episodes(cfg, episodes, seed)` draws
the placement from the world's stream only, so the levels config and its single-height twin
(levels = 1, the paper's world) start from the same agent and target cells. No oracle column
(Held-Karp over 15 targets per episode would cost more than the whole measurement): moves,
flight time and targets found are what the issue's goals read.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import BatchGridWorld, DetectionTable, GridConfig, sample_episodes

from ..base import Policy, observe

#: the policies of the altitude table: row -> (registered policy, kwargs, fly with levels?)
ROWS: dict[str, tuple[str, dict[str, Any], bool]] = {
    "belief (single height)": ("belief", {}, False),
    "belief (levels)": ("belief", {}, True),
    "lawnmower (tiling height)": ("lawnmower-high", {}, True),
    "ns (level 1)": ("ns", {}, True),
}


@dataclass(frozen=True)
class AltitudeSetting:
    """One episode class of the table: the grid, its targets and how they are placed and move."""

    label: str
    width: int
    height: int
    targets: int
    t_e: int = 300
    distribution: str = "random"
    motion: str = "static"
    #: gaussian placement and the lattices, scaled with the field (the paper's 10 x 10 values
    #: doubled on 20 x 20: mean (3, 5) -> (6, 10), sd 1 -> 2, spacing 2 -> 4)
    gaussian_mean: tuple[float, float] = (3.0, 5.0)
    gaussian_sd: float = 1.0
    grid_spacing: int = 2

    def config(self, levels: int, detection: DetectionTable | None) -> GridConfig:
        return GridConfig(width=self.width, height=self.height, n_targets=self.targets, t_e=self.t_e,
                          distribution=self.distribution, motion=self.motion,  # type: ignore[arg-type]
                          map_variant="spatiotemporal" if self.motion != "static" else "spatial",
                          gaussian_mean=self.gaussian_mean, gaussian_sd=self.gaussian_sd,
                          grid_spacing=self.grid_spacing,
                          levels=levels, detection=detection if levels > 1 else None)


SETTINGS: tuple[AltitudeSetting, ...] = (
    AltitudeSetting("random 10x10/5", 10, 10, 5),
    AltitudeSetting("random 20x20/10", 20, 20, 10),
    AltitudeSetting("random 30x30/15, t_e 1000", 30, 30, 15, t_e=1000),
    # the quality table's other classes (policy.evaluation.quality.SETTINGS) on 20 x 20 / 10
    AltitudeSetting("gaussian 20x20/10", 20, 20, 10, distribution="gaussian", gaussian_mean=(6.0, 10.0),
                    gaussian_sd=2.0),
    AltitudeSetting("equidistant 20x20/10", 20, 20, 10, distribution="equidistant", grid_spacing=4),
    # moving targets: t_e 1000 (at 300 a fifth to a half of the single-height episodes end
    # with targets left, and the mean reads the limit)
    AltitudeSetting("random walk 20x20/10, t_e 1000", 20, 20, 10, t_e=1000, motion="random_walk"),
    AltitudeSetting("herd 20x20/10, t_e 1000", 20, 20, 10, t_e=1000, distribution="equidistant", motion="herd",
                    grid_spacing=4),
)


def run_rows(policy: Policy, cfg: GridConfig, episodes: int, seed: int, batch: int = 500) -> dict[str, np.ndarray]:
    """One policy on `episodes` episodes of cfg: per-episode moves, targets found, seconds of
    flight, and the share of moves flown above level 1. Batch b is seeded seed + its start."""
    ep_all = sample_episodes(cfg, episodes, seed)
    moves, found, flight, high = [], [], [], []
    for b0 in range(0, episodes, batch):
        ep = ep_all.subset(slice(b0, b0 + batch))
        policy.reset(cfg, len(ep), seed + b0, ep if policy.needs_truth else None)
        world = BatchGridWorld(ep, seed + b0, off_map=policy.off_map)
        above = np.zeros(len(ep), np.int64)
        while not world.done.all():
            active = ~world.done
            world.step(policy.act(observe(world)))
            above += active & (world.level > 1)
        moves.append(world.t.copy())
        found.append(world.found.sum(axis=1))
        flight.append(world.flight_s.copy())
        high.append(above)
    return {"moves": np.concatenate(moves), "found": np.concatenate(found),
            "flight_s": np.concatenate(flight), "moves_above_1": np.concatenate(high)}


def altitude_task(row: str, setting: str, levels: int, detection: dict, episodes: int, seed: int) -> dict[str, Any]:
    """One (row, setting) cell, from plain arguments (fan_out ships it to a process)."""
    from ..baselines import make_policy

    st = {s.label: s for s in SETTINGS}[setting]
    name, kw, with_levels = ROWS[row]
    table = DetectionTable.from_dict(detection)
    cfg = st.config(levels if with_levels else 1, table)
    t0 = time.perf_counter()
    r = run_rows(make_policy(name, cfg, **kw), cfg, episodes, seed)
    return {
        "levels": cfg.levels,
        "mean_moves": float(r["moves"].mean()),
        "p90_moves": float(np.percentile(r["moves"], 90)),
        "all_found_pct": float(100.0 * np.mean(r["found"] == cfg.n_targets)),
        "mean_flight_s": float(r["flight_s"].mean()),
        "share_moves_above_level_1": float(r["moves_above_1"].sum() / max(r["moves"].sum(), 1)),
        "episodes": episodes,
        "seconds": round(time.perf_counter() - t0, 1),
        "moves": r["moves"].tolist(),
    }


def run_altitude(detection: DetectionTable, levels: int = 3, episodes: int = 2000, seed: int = 0,
                 rows: tuple[str, ...] = tuple(ROWS), settings: tuple[str, ...] | None = None,
                 workers: int | None = 1) -> dict[str, Any]:
    """Every (row, setting) cell; each row's ratio to the single-height belief per setting,
    the mean of per-episode ratios too (paired on the same episodes)."""
    from ..fanout import fan_out

    labels = settings or tuple(s.label for s in SETTINGS)
    tasks = [(row, label, levels, detection.to_dict(), episodes, seed) for label in labels for row in rows]
    cells = fan_out(altitude_task, tasks, workers=workers)
    table: dict[str, dict[str, Any]] = {label: {} for label in labels}
    for (row, label, *_), c in zip(tasks, cells, strict=True):
        table[label][row] = c
    base = "belief (single height)"
    for label in labels:
        ref = table[label].get(base)
        for c in table[label].values():
            m = np.asarray(c.pop("moves"), float)
            if ref is not None:
                c["ratio_to_single_height"] = c["mean_moves"] / ref["mean_moves"]
                c["_m"] = m
        if ref is not None:
            rm = ref["_m"]
            for c in table[label].values():
                c["mean_paired_ratio"] = float(np.mean(c["_m"] / rm))
                c["episodes_worse_pct"] = float(100.0 * np.mean(c["_m"] > rm))
            for c in table[label].values():
                c.pop("_m", None)
    cfg = {"levels": levels, "settings": [dataclasses.asdict(s) for s in SETTINGS if s.label in labels],
           "rows": {r: list(ROWS[r][:2]) + [ROWS[r][2]] for r in rows}, "detection": detection.to_dict()}
    return stamp(cfg, seed, episodes=episodes, table=table)


def write_altitude(doc: dict[str, Any], out: Path, note: str = "", command: str = "") -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    js, md = out / "altitude.json", out / "altitude.md"
    atomic_write_json(js, doc)
    lines = ["# Search from any height (issue 27)", ""]
    if note:
        lines += [note, ""]
    if command:
        lines += ["Command:", "", "    " + command, ""]
    det = doc["config"]["detection"]
    lines += [f"Levels L = {doc['config']['levels']}; {doc['episodes']} test episodes per cell, test seed "
              f"{doc['seed']} (the single-height weights were tuned on seeds 777 and 4242, the altitude rule's on 777, its moving-target chase and its route on 12345); git {doc.get('git_revision')}.",
              "", f"Detection table: p_detect {det['p_detect']}, false alarms per cell "
              f"{det['false_alarm_per_cell']}, heights {det['height_m']} m.", ""]
    for label, rows in doc["table"].items():
        lines += [f"## {label}", "", "| policy | levels | mean moves | p90 | all found % | flight s | x single height "
                  "| paired ratio | worse episodes % | moves above level 1 % |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for row, c in rows.items():
            lines.append(
                f"| {row} | {c['levels']} | {c['mean_moves']:.1f} | {c['p90_moves']:.0f} | {c['all_found_pct']:.1f} | "
                f"{c['mean_flight_s']:.1f} | {c.get('ratio_to_single_height', float('nan')):.3f} | "
                f"{c.get('mean_paired_ratio', float('nan')):.3f} | {c.get('episodes_worse_pct', float('nan')):.1f} | "
                f"{100 * c['share_moves_above_level_1']:.1f} |")
        lines.append("")
    with atomic_open(md, "w") as f:
        f.write("\n".join(lines))
    return [js, md]


PROVISIONAL_NOTE = ("Provisional table (the issue 27 brief's example, written to a temporary file): the lead "
                    "re-measures with the table measured on the SITL's camera (sim/gridworld/data/detection.json).")


def main(argv: list[str] | None = None) -> None:
    """`python -m policy.evaluation.altitude --detection TABLE.json [--episodes N] [--seed S]
    [--workers W] [--out results/altitude] [--note TEXT] [--setting LABEL]... [--row ROW]...`:
    the table of issue 27's measurement
    (a module entry point like benchmarks/: the measurement is not a user command)."""
    import argparse
    import shlex
    import sys

    ap = argparse.ArgumentParser(prog="python -m policy.evaluation.altitude", description=main.__doc__)
    ap.add_argument("--detection", type=Path, required=True, help="detection table JSON")
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument("--episodes", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("results/altitude"))
    ap.add_argument("--note", default=PROVISIONAL_NOTE)
    ap.add_argument("--setting", action="append", help="settings to run (default: all)")
    ap.add_argument("--row", action="append", choices=tuple(ROWS),
                    help="rows to run (default: all; a ratio column needs 'belief (single height)')")
    a = ap.parse_args(argv)
    table = DetectionTable.load(a.detection)
    doc = run_altitude(table, a.levels, a.episodes, a.seed, settings=tuple(a.setting) if a.setting else None,
                       rows=tuple(a.row) if a.row else tuple(ROWS), workers=a.workers)
    cmd = "PYTHONPATH=. python -m policy.evaluation.altitude " + shlex.join(sys.argv[1:] if argv is None else argv)
    for p in write_altitude(doc, a.out, note=a.note, command=cmd):
        print(p)


if __name__ == "__main__":
    main()
