"""Flights vs the grid world, over many seeds: the numbers behind "the flight flies the policy".

Each seed is one real flight (a SITL vehicle in-process, the companion's policy service over
MAVLink on loopback UDP, PyBullet physics and camera) and the same policy on the same episode
in the grid world. Flights fan out over worker processes, each with its own SITL instance (its
own ports), so two flights never share a link. Rows are written as Markdown and JSON with the
provenance of the run.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open, atomic_write_json, stamp

#: goal of issue 14: mean flight/grid ratio and the worst single flight
GOAL_MEAN_RATIO, GOAL_MAX_RATIO = 1.15, 1.5


@dataclass(frozen=True)
class FlightJob:
    seed: int
    speedup: float = 10.0
    gps_sigma_m: float | None = None
    visit_map: str = "probabilistic"
    max_moves: int | None = None
    policy: str | None = None  # None: the default flight policy
    out: str | None = None  # keep each flight's files here (None: a temporary folder)
    #: who flies: our SITL vehicle, or a real ardupilot / px4 binary on our world (sim.bridges)
    autopilot: str = "ours"
    camera: str = "mavlink"  # mavlink | video (the SITL's RTP/H.264 stream, decoded by PyAV)
    #: the field's size (width, height, |R|; None: the flight's default 10 x 10 / 5) and the
    #: altitude levels the companion flies (docs/altitude.md) with a detection table (a JSON
    #: path; None: the measured one shipped with sim.gridworld)
    size: tuple[int, int, int] | None = None
    levels: int = 1
    detection: str | None = None
    #: a real field's field.json (`uavsearch field`): flown inside its polygon (our vehicle);
    #: None, the rectangle
    field: str | None = None

    def grid(self):
        """The GridConfig flown, or None for the flight's default field (today's flights)."""
        if self.size is None and self.levels == 1 and self.detection is None:
            return None
        from sim.gridworld import DetectionTable, GridConfig

        w, h, r = self.size if self.size is not None else (10, 10, 5)
        table = DetectionTable.load(self.detection) if self.detection is not None else None
        return GridConfig(width=w, height=h, n_targets=r, levels=self.levels, detection=table)

    def __post_init__(self) -> None:
        if self.speedup < 0:
            raise ValueError(f"speedup must be >= 0 (got {self.speedup})")
        if self.gps_sigma_m is not None and not self.gps_sigma_m > 0:
            raise ValueError(f"gps_sigma_m must be > 0 (got {self.gps_sigma_m})")
        if self.visit_map not in ("probabilistic", "hard"):
            raise ValueError(f"visit_map must be 'probabilistic' or 'hard' (got {self.visit_map!r})")


def fly_one(job: FlightJob) -> dict[str, Any]:
    """One flight in this worker's SITL instance; the row of the table."""
    from missions.flight import fly_search

    pf = None
    if job.field is not None:
        from missions.field_run import load_polygon

        pf = load_polygon(Path(job.field))
    with tempfile.TemporaryDirectory(prefix="flight-") as tmp:
        out = Path(job.out) / f"seed{job.seed}" if job.out else Path(tmp)
        r = fly_search(out, seed=job.seed, speedup=job.speedup, max_moves=job.max_moves, policy=job.policy,
                       gps_sigma_m=job.gps_sigma_m, visit_map=job.visit_map, plot=job.out is not None,
                       free_ports=True, autopilot=job.autopilot, camera=job.camera, grid=job.grid(),
                       **({} if pf is None else {"field": pf}))
    keep = ("policy", "moves", "grid_moves", "flight_grid_ratio", "optimal_moves", "believed_found", "truly_found",
            "targets", "schedule_slips", "late_frames", "late_inputs", "lockstep_timeouts", "frames_missing", "nees_mean",
            "nees_inside_95", "nees", "simulated_s", "wall_s", "error", "cells", "search_s", "levels_flown")
    # the move cap: the job's, else the episode's t_e (the flight's default)
    cap = job.max_moves if job.max_moves is not None else int(r["config"]["t_e"])
    capped = r["moves"] >= cap and r["believed_found"] < r["targets"]
    return {"seed": job.seed, "gps_sigma_m": job.gps_sigma_m, "visit_map": job.visit_map, "capped": capped,
            "levels": job.levels, **{k: r.get(k) for k in keep},
            **({} if pf is None else {"field_checks": r["field_checks"]})}


def fly_many(jobs: list[FlightJob], workers: int = 2) -> list[dict[str, Any]]:
    """Fly the jobs over `workers` processes (spawned: PyBullet and threads do not fork); each
    flight's SITL takes UDP ports the OS hands out, so flights never share a link."""
    if workers < 1:
        raise ValueError(f"workers must be >= 1 (got {workers})")
    if workers == 1:
        return [fly_one(j) for j in jobs]
    with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
        return list(ex.map(fly_one, jobs))


def summarise(rows: list[dict[str, Any]], bias_tau_s: float = 60.0) -> dict[str, Any]:
    """Ratios, finds and the posterior's consistency over the flights without an error.

    The NEES interval: decisions 4 s apart share the GPS bias (tau 60 s), so the chi-square 95 %
    interval of the mean counts one independent sample per tau of flown time (n_eff); the
    interval for as many samples as decisions (strict) is given too."""
    from scipy.stats import chi2

    ok = [r for r in rows if r["error"] is None and r["flight_grid_ratio"] is not None]
    ratios = np.array([r["flight_grid_ratio"] for r in ok]) if ok else np.zeros(0)
    nees = np.concatenate([r["nees"] for r in ok if r["nees"]]) if any(r["nees"] for r in ok) else np.zeros(0)
    found = sum(r["truly_found"] for r in ok)
    over = int((ratios > GOAL_MAX_RATIO).sum())
    n_eff = max(sum(len(r["nees"]) for r in ok) * 4.0 / bias_tau_s, 1.0)
    eff = (chi2.ppf([0.025, 0.975], 2 * n_eff) / n_eff).tolist()
    strict = (chi2.ppf([0.025, 0.975], 2 * max(len(nees), 1)) / max(len(nees), 1)).tolist()
    return {
        "flights": len(rows), "errors": len(rows) - len(ok), "capped": int(sum(r.get("capped", False) for r in ok)),
        "ratio_mean": float(ratios.mean()) if len(ratios) else None,
        "ratio_mean_ci95": ratio_mean_interval(ratios),
        "over_1_5_ci95": over_interval(over, len(ratios)),
        "ratio_median": float(np.median(ratios)) if len(ratios) else None,
        "ratio_max": float(ratios.max()) if len(ratios) else None,
        "over_1_5": over,
        "moves_mean": float(np.mean([r["moves"] for r in ok])) if ok else None,
        "grid_moves_mean": float(np.mean([r["grid_moves"] for r in ok])) if ok else None,
        "found_pct": 100.0 * found / max(sum(r["targets"] for r in ok), 1),
        "believed_pct": 100.0 * sum(r["believed_found"] for r in ok) / max(sum(r["targets"] for r in ok), 1),
        "nees_mean": float(nees.mean()) if len(nees) else None,
        "nees_samples": int(len(nees)), "nees_n_eff": n_eff, "nees_interval_eff": eff, "nees_interval_strict": strict,
        "nees_inside_95": float(np.mean(nees < 5.991464547107979)) if len(nees) else None,
        "schedule_slips": int(sum(r["schedule_slips"] for r in ok)),
        "late_frames": int(sum(r.get("late_frames", 0) for r in ok)),
        "late_inputs": int(sum(r.get("late_inputs", 0) for r in ok)),
        "search_s_mean": float(np.mean([r["search_s"] for r in ok])) if ok and all(r.get("search_s") is not None
                                                                                  for r in ok) else None,
        "goal_met": bool(len(ratios) and not any(r.get("capped") for r in ok) and len(ok) == len(rows)
                         and ratios.mean() <= GOAL_MEAN_RATIO and ratios.max() <= GOAL_MAX_RATIO),
        **_field_summary(rows, ok, ratios),
    }


#: issue 28's goal on a real field: every target truly found, no setpoint off the field or in a
#: no-fly zone, no fence breach, and the mean flight/grid ratio at most this
GOAL_FIELD_MEAN_RATIO = 1.1
#: the field checks (missions.field_checks) summed over flights that the goal wants 0
FIELD_ZERO = ("setpoints_outside_fence", "setpoints_off_field", "breaches", "fence_rejections")


def _field_summary(rows: list[dict[str, Any]], ok: list[dict[str, Any]], ratios: np.ndarray) -> dict[str, Any]:
    """Flights over a real field: the checks summed (over every flight, errors included) and
    issue 28's goal; nothing for flights over the rectangle."""
    checked = [r["field_checks"] for r in rows if "field_checks" in r]
    if not checked:
        return {}
    totals = {k: int(sum(c.get(k, 0) for c in checked))
              for k in ("setpoints", "setpoints_meant", "setpoints_outside_rings", *FIELD_ZERO, "true_off_field")}
    # beside the goal: where the vehicle truly went (its position error, not a setpoint)
    totals["true_off_field_flights"] = int(sum(c["true_off_field"] > 0 for c in checked))
    totals["true_off_field_max_m"] = float(max(c.get("true_off_field_max_m", 0.0) for c in checked))
    all_found = bool(ok) and all(r["truly_found"] == r["targets"] for r in ok)
    met = bool(len(ok) == len(rows) and all_found and not any(totals[k] for k in FIELD_ZERO)
               and len(ratios) and ratios.mean() <= GOAL_FIELD_MEAN_RATIO)
    return {"field_checks": totals, "all_truly_found": all_found, "field_goal_met": met}


#: resamples of the bootstrap interval of the mean ratio (seeded: the same rows, the same interval)
BOOTSTRAP = 10_000


def ratio_mean_interval(ratios: np.ndarray, seed: int = 0) -> list[float] | None:
    """95 % percentile-bootstrap interval of the mean flight/grid ratio. Why a bootstrap: the
    ratios are heavy-tailed (most flights 0.9-1.1, a few 2-4.6), so a normal interval would
    mislead; one set of 20 swung its mean from 1.09 to 1.35 with three flights."""
    if len(ratios) < 2:
        return None
    rng = np.random.default_rng([seed, 0xB007])
    means = np.asarray(ratios)[rng.integers(0, len(ratios), (BOOTSTRAP, len(ratios)))].mean(axis=1)
    return [float(v) for v in np.percentile(means, [2.5, 97.5])]


def over_interval(k: int, n: int) -> list[float] | None:
    """95 % Clopper-Pearson interval of the fraction of flights over the ratio goal (k of n):
    0 of 20 still allows up to 17 %."""
    from scipy.stats import beta

    if n < 1:
        return None
    lo = 0.0 if k == 0 else float(beta.ppf(0.025, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(0.975, k + 1, n - k))
    return [lo, hi]


def flight_vs_grid(seeds: list[int], out: Path, workers: int = 2, speedup: float = 10.0,
                   policy: str | None = None, max_moves: int | None = None, autopilot: str = "ours",
                   camera: str = "mavlink", size: tuple[int, int, int] | None = None, levels: int = 1,
                   detection: str | None = None, command: str = "python -m missions flight-table",
                   field: Path | None = None) -> dict[str, Any]:
    """Fly every seed, compare with the grid world, write out/flight_vs_grid.{md,json}
    (flight_vs_grid_<autopilot>.* when a real autopilot flies; _WxH_R and _levelsL for another
    field size and altitude levels; flight_vs_grid_field_<name>.* over a real field, `field`
    its field.json, named by its folder)."""
    from missions.flight_policy import FLIGHT_POLICY

    if field is not None and size is not None:
        raise ValueError("a real field sets its own grid (no size)")
    t0 = time.monotonic()
    fpath = None if field is None else str(Path(field))
    rows = fly_many([FlightJob(s, speedup, policy=policy, max_moves=max_moves, autopilot=autopilot, camera=camera,
                               size=size, levels=levels, detection=detection, field=fpath) for s in seeds], workers)
    summary = summarise(rows)
    extra: dict[str, Any] = {} if size is None and levels == 1 and detection is None else {
        "field": list(size) if size is not None else None, "levels": levels, "detection": detection}
    if field is not None:
        from missions.field_run import load_polygon

        pf = load_polygon(Path(field))
        extra = {"field": {"file": fpath, "source": pf.source, "heading_deg": pf.heading_deg, "width": pf.width,
                           "height": pf.height, "searchable_cells": pf.searchable_cells}}
        if "--field" not in command:
            command += f" --field {fpath}"
    doc = stamp({"seeds": seeds, "speedup": speedup, "workers": workers, "policy": policy or FLIGHT_POLICY,
                 "max_moves": max_moves, "visit_map": "probabilistic", "companion_lockstep": autopilot == "ours",
                 "autopilot": autopilot, "camera": camera, **extra},
                 seeds[0] if seeds else None, summary=summary, rows=rows, wall_s=time.monotonic() - t0,
                 cpus=os.cpu_count(), command=command)
    stem = "flight_vs_grid" + ("" if autopilot == "ours" else f"_{autopilot}") + ("" if camera == "mavlink" else
                                                                                   f"_{camera}")
    stem += "" if size is None else f"_{size[0]}x{size[1]}_{size[2]}"
    stem += "" if levels == 1 else f"_levels{levels}"
    if field is not None:
        stem += f"_field_{Path(field).resolve().parent.name}"
    write_result(out, stem, doc, render_md(doc))
    return doc


def write_result(out: Path, stem: str, doc: dict[str, Any], markdown: str) -> None:
    """out/stem.json (the document with its provenance) and out/stem.md (what a person reads),
    each written atomically."""
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / f"{stem}.json", doc)
    with atomic_open(out / f"{stem}.md", "w") as f:
        f.write(markdown)


def render_md(doc: dict[str, Any]) -> str:
    s, rows = doc["summary"], doc["rows"]
    lines = [
        "# Flights vs the grid world" + ("" if doc["config"].get("autopilot", "ours") == "ours" else
                                         f" (the real {doc['config']['autopilot']} flying our world)")
        + ("" if doc["config"].get("camera", "mavlink") == "mavlink" else " (frames from the RTP/H.264 video stream)"),
        "",
        f"{s['flights']} flights (seeds {doc['config']['seeds'][0]}..{doc['config']['seeds'][-1]}), policy "
        f"`{doc['config']['policy']}`, probabilistic visitation map, speed-up {doc['config']['speedup']}, "
        f"{doc['config']['workers']} worker processes; git {doc['git_revision']}; {doc['wall_s'] / 60:.1f} min wall. "
        f"Command: `{doc['command']}`. Each flight: SITL (PyBullet) + companion over MAVLink/UDP, decisions "
        "every 4 simulated s; grid moves: the same policy on the same episode in the grid world.",
        "",
        *_summary_lines(s),
        "",
        *_field_lines(doc),
        *_row_lines(rows),
    ]
    return "\n".join(lines) + "\n"


def _field_lines(doc: dict[str, Any]) -> list[str]:
    """Over a real field: which, and its checks against issue 28's goal (nothing otherwise)."""
    s, f = doc["summary"], doc["config"].get("field")
    if f is None or "field_checks" not in s:
        return []
    c = s["field_checks"]
    return [
        f"Real field `{f['file']}` ({f['source']}): {f['width']} x {f['height']} grid at {f['heading_deg']:.2f} deg, "
        f"{f['searchable_cells']} searchable cells. **Issue 28's goal (every target truly found, no setpoint off "
        f"the field or in a no-fly zone, no fence breach, mean flight/grid <= {GOAL_FIELD_MEAN_RATIO}): "
        f"{'met' if s['field_goal_met'] else 'NOT met'}**. "
        f"All truly found: {s['all_truly_found']}. Setpoints the vehicle heard: {c['setpoints']}, outside the "
        f"uploaded fence: {c['setpoints_outside_fence']}; places the {c['setpoints_meant']} setpoints sent the "
        f"vehicle truly, off the field or in a no-fly zone: {c['setpoints_off_field']}; position estimates "
        f"outside the fence (breaches): {c['breaches']}; the vehicle's fence rejections: {c['fence_rejections']}; "
        f"setpoints heard outside the field's rings as drawn (in the estimate's frame, shifted by the bias; "
        f"information): {c['setpoints_outside_rings']}. Beside the goal, where the vehicle truly went: "
        f"{c['true_off_field']} simulator ticks (of 50 a second) off the field or over a no-fly zone, in "
        f"{c['true_off_field_flights']} flight(s), at most {c['true_off_field_max_m']:.2f} m past the ring.",
        "",
    ]


def _summary_lines(s: dict[str, Any]) -> list[str]:
    """The summary paragraphs: the ratio against its goal, finds, the posterior's consistency."""
    return [
        f"**flight/grid moves: mean {_f(s['ratio_mean'])}, max {_f(s['ratio_max'])}, flights over 1.5: "
        f"{s['over_1_5']}** (goal: mean <= {GOAL_MEAN_RATIO}, none over {GOAL_MAX_RATIO}: "
        f"{'met' if s['goal_met'] else 'NOT met'}); median {_f(s['ratio_median'])}; flights stopped at the move "
        f"cap: {s['capped']}. Targets found (truth): {s['found_pct']:.1f} %, believed {s['believed_pct']:.1f} %."
        + _intervals(s),
        "",
        f"Position posterior vs the simulator's truth: mean NEES {_f(s['nees_mean'])} over {s['nees_samples']} "
        f"decisions (2 expected; chi-square 95 % interval {_f(s['nees_interval_eff'][0])}-"
        f"{_f(s['nees_interval_eff'][1])} for n_eff = {s['nees_n_eff']:.0f} independent samples, one per bias "
        f"correlation time; {_f(s['nees_interval_strict'][0])}-{_f(s['nees_interval_strict'][1])} if every "
        f"decision were independent), {_pct(s['nees_inside_95'])} of samples inside the 95 % bound. Schedule "
        f"slips: {s['schedule_slips']}, late frames: {s['late_frames']}, inputs waited for in vain: "
        f"{s.get('late_inputs', 0)}. Errors: {s['errors']}.",
    ]


def _row_lines(rows: list[dict[str, Any]]) -> list[str]:
    lines = [
        "| seed | flight moves | grid moves | ratio | optimal | found (truth) | believed | slips | mean NEES | wall s |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['seed']} | {'>=' if r.get('capped') else ''}{r['moves']} | {r['grid_moves']} | {r['flight_grid_ratio']:.2f} | "
                     f"{r['optimal_moves']} | {r['truly_found']}/{r['targets']} | {r['believed_found']} | "
                     f"{r['schedule_slips']} | {_f(r['nees_mean'])} | {r['wall_s']:.0f} |"
                     + (f" error: {r['error']}" if r["error"] else ""))
    return lines


#: what flight tables pooled together must share (their flights flew the same thing)
POOL_KEYS = ("policy", "speedup", "visit_map", "max_moves")


def pool_tables(paths: list[Path], out: Path) -> dict[str, Any]:
    """Pool flight tables (flight_vs_grid.json files, e.g. seeds 0-19, 20-39, ...) flown by one
    git revision with one configuration into one summary over all their flights, written to
    out/flight_pool.{md,json}. Why: a set of 20 flights has heavy tails (three flights moved one
    set's mean from 1.09 to 1.35), so a judgement wants a hundred flights and intervals. Tables
    of different revisions, configurations or overlapping seeds are refused, naming the file."""
    import json

    if not paths:
        raise ValueError("no flight tables to pool")
    tables: list[tuple[Path, list[dict[str, Any]], dict[str, Any], str]] = []  # path, rows, config, revision
    for p in paths:
        try:
            doc = json.loads(Path(p).read_text())
            tables.append((Path(p), doc["rows"], doc["config"], doc["git_revision"]))
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise ValueError(f"{p}: not a flight table (flight_vs_grid.json): {e}") from e
    first, _, cfg0, rev0 = tables[0]
    seen: dict[int, Path] = {}
    for p, rows, cfg, rev in tables:
        if rev != rev0:
            raise ValueError(f"{p}: flown at git {rev}, {first} at {rev0}: pool one revision's flights")
        for k in POOL_KEYS:
            if cfg.get(k) != cfg0.get(k):
                raise ValueError(f"{p}: {k} {cfg.get(k)!r} differs from {first}'s {cfg0.get(k)!r}")
        for r in rows:
            if r["seed"] in seen:
                raise ValueError(f"{p}: seed {r['seed']} is in {seen[r['seed']]} too")
            seen[r["seed"]] = p
    rows = sorted((r for _, rs, _, _ in tables for r in rs), key=lambda r: r["seed"])
    sets = []
    for p, rs, _, _ in tables:
        s = summarise(rs)
        sets.append({"table": str(p), "seeds": [min(r["seed"] for r in rs), max(r["seed"] for r in rs)],
                     **{k: s[k] for k in ("flights", "ratio_mean", "ratio_max", "over_1_5", "nees_mean",
                                          "nees_interval_eff", "nees_inside_95", "found_pct")}})
    doc = stamp({**{k: cfg0.get(k) for k in POOL_KEYS}, "flights_git_revision": rev0,
                 "tables": [str(p) for p, *_ in tables], "seeds": [r["seed"] for r in rows]}, None,
                summary=summarise(rows), sets=sets, rows=rows, command="python -m missions flight-pool")
    write_result(out, "flight_pool", doc, render_pool_md(doc))
    return doc


def render_pool_md(doc: dict[str, Any]) -> str:
    s, c = doc["summary"], doc["config"]
    lines = [
        "# Flights vs the grid world, pooled",
        "",
        f"{s['flights']} flights from {len(doc['sets'])} tables, policy `{c['policy']}`, speed-up {c['speedup']}; "
        f"flown at git {c['flights_git_revision']}; pooled at git {doc['git_revision']}. Command: `{doc['command']}`.",
        "",
        *_summary_lines(s),
        "",
        "| table | seeds | flights | mean ratio | max | over 1.5 | mean NEES (interval) | in 95 % bound | found |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for t in doc["sets"]:
        lines.append(f"| {t['table']} | {t['seeds'][0]}-{t['seeds'][1]} | {t['flights']} | {_f(t['ratio_mean'])} | "
                     f"{_f(t['ratio_max'])} | {t['over_1_5']} | {_f(t['nees_mean'])} ({_f(t['nees_interval_eff'][0])}-"
                     f"{_f(t['nees_interval_eff'][1])}) | {_pct(t['nees_inside_95'])} | {t['found_pct']:.0f} % |")
    return "\n".join([*lines, "", *_row_lines(doc["rows"])]) + "\n"


def _intervals(s: dict[str, Any]) -> str:
    """The 95 % intervals of the mean ratio and of the fraction over 1.5 (older files lack them)."""
    ci, over = s.get("ratio_mean_ci95"), s.get("over_1_5_ci95")
    parts = []
    if ci:
        parts.append(f"mean ratio {_f(ci[0])}-{_f(ci[1])} (bootstrap)")
    if over:
        parts.append(f"flights over 1.5 {_pct(over[0])}-{_pct(over[1])} (Clopper-Pearson)")
    return f" 95 % intervals: {'; '.join(parts)}." if parts else ""


def _f(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.2f}"


def _pct(x: float | None) -> str:
    return "n/a" if x is None else f"{100 * x:.0f} %"


__all__ = ["FlightJob", "asdict", "flight_vs_grid", "fly_many", "pool_tables", "render_md", "summarise"]


def gps_noise_table(sigmas: list[float], maps: list[str], seeds: list[int], out: Path, workers: int = 2,
                    speedup: float = 10.0, policy: str | None = None, max_moves: int | None = 150) -> dict[str, Any]:
    """Real flights per (GPS sigma, visitation map): moves and targets found, written to
    out/gps_noise.{md,json}. Every row flies the same seeds (paired episodes)."""
    from missions.flight_policy import FLIGHT_POLICY

    t0 = time.monotonic()
    jobs = [FlightJob(s, speedup, gps_sigma_m=g, visit_map=m, max_moves=max_moves, policy=policy)
            for g in sigmas for m in maps for s in seeds]
    rows = fly_many(jobs, workers)
    table = []
    for g in sigmas:
        for m in maps:
            sub = [r for r in rows if r["gps_sigma_m"] == g and r["visit_map"] == m]
            table.append({"gps_sigma_m": g, "visit_map": m, **summarise(sub)})
    doc = stamp({"sigmas": sigmas, "maps": maps, "seeds": seeds, "speedup": speedup, "workers": workers,
                 "policy": policy or FLIGHT_POLICY, "max_moves": max_moves, "companion_lockstep": True},
                seeds[0] if seeds else None, table=table, rows=[{k: v for k, v in r.items() if k != "cells"} for r in rows],
                wall_s=time.monotonic() - t0, cpus=os.cpu_count(), command="python -m missions gps-table")
    lines = [
        "# Search flights under GPS noise",
        "",
        f"{len(seeds)} real flights per row (seeds {seeds[0]}..{seeds[-1]}, the same in every row), policy "
        f"`{doc['config']['policy']}`, at most {max_moves} moves, speed-up {speedup}, {workers} worker processes; "
        f"git {doc['git_revision']}; {doc['wall_s'] / 60:.1f} min wall. Command: `{doc['command']}`. GPS sigma: "
        "the receiver's total horizontal error per axis (white noise and Gauss-Markov bias scaled together from "
        "the default 0.6 m + 0.7 m); the companion's filter models both. hard: visits mark the believed cell; "
        "probabilistic: visits spread over the position posterior.",
        "",
        "| GPS sigma (m) | map | moves (mean) | grid moves (mean) | flight/grid (mean, max) | found % (truth) "
        "| at cap | mean NEES | errors |",
        "|---:|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for t in table:
        lines.append(f"| {t['gps_sigma_m']} | {t['visit_map']} | {_f(t['moves_mean'])} | {_f(t['grid_moves_mean'])} | "
                     f"{_f(t['ratio_mean'])}, {_f(t['ratio_max'])} | {t['found_pct']:.1f} | {t['capped']} | "
                     f"{_f(t['nees_mean'])} | {t['errors']} |")
    write_result(out, "gps_noise", doc, "\n".join(lines) + "\n")
    return doc
