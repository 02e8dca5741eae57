"""Real flights with altitude levels against the same seeds flown at one height: does the
companion fly the levels' plan (flight/grid moves), find every target, and search in less
flight time? (issue 27's flight half; docs/altitude.md.)

Both sets are ordinary flight tables (missions.flight_table: each written as its own
flight_vs_grid_*.md/json); this module flies them and writes the two side by side, per seed,
as flight_levels.{md,json} with the provenance of the run.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from provenance import stamp

#: goals of the levels' flights: mean flight/grid moves and the worst single flight
GOAL_MEAN_RATIO, GOAL_MAX_RATIO = 1.1, 1.5


def level_changes(levels_flown: list[int] | None) -> int:
    """Climbs and descents in a flight's per-decision levels."""
    if not levels_flown:
        return 0
    lv = np.asarray(levels_flown)
    return int(np.count_nonzero(np.diff(lv)))


def compare_levels(seeds: list[int], out: Path, field: tuple[int, int, int], levels: int, baseline: int = 1,
                   workers: int = 1, speedup: float = 10.0, detection: str | None = None, policy: str | None = None,
                   max_moves: int | None = None, command: str = "python -m missions flight-table") -> dict[str, Any]:
    """Fly the seeds at `levels` and at `baseline` levels on the same field, write both flight
    tables and out/flight_levels.{md,json}; returns the comparison document."""
    from missions.flight_table import flight_vs_grid, write_result

    if levels == baseline:
        raise ValueError(f"levels and the baseline's must differ (both {levels})")
    t0 = time.monotonic()
    docs = {lv: flight_vs_grid(seeds, out, workers, speedup, policy, max_moves, field=field, levels=lv,
                               detection=detection if lv > 1 else None, command=command)
            for lv in (levels, baseline)}
    a, b = docs[levels], docs[baseline]
    sa, sb = a["summary"], b["summary"]
    ok = sa["errors"] == 0 and sa["capped"] == 0
    goals = {
        "ratio_mean": bool(ok and sa["ratio_mean"] is not None and sa["ratio_mean"] <= GOAL_MEAN_RATIO),
        "ratio_max": bool(ok and sa["ratio_max"] is not None and sa["ratio_max"] <= GOAL_MAX_RATIO),
        "found_100": bool(ok and sa["found_pct"] == 100.0),
        "search_s_below": bool(sa.get("search_s_mean") is not None and sb.get("search_s_mean") is not None
                               and sa["search_s_mean"] < sb["search_s_mean"]),
    }
    by_seed = {r["seed"]: r for r in b["rows"]}
    pairs = [{"seed": r["seed"], "levels": _row(r), "baseline": _row(by_seed.get(r["seed"]))} for r in a["rows"]]
    doc = stamp({"seeds": seeds, "field": list(field), "levels": levels, "baseline_levels": baseline,
                 "detection": detection, "speedup": speedup, "workers": workers, "policy": a["config"]["policy"],
                 "max_moves": max_moves, "tables_git_revision": a["git_revision"]},
                seeds[0] if seeds else None, summary={"levels": sa, "baseline": sb}, goals=goals, pairs=pairs,
                wall_s=time.monotonic() - t0, command=command)
    write_result(out, "flight_levels", doc, render_md(doc))
    return doc


def _row(r: dict[str, Any] | None) -> dict[str, Any] | None:
    if r is None:
        return None
    return {k: r.get(k) for k in ("moves", "grid_moves", "flight_grid_ratio", "truly_found", "believed_found",
                                  "targets", "search_s", "schedule_slips", "capped", "error")} | {
        "level_changes": level_changes(r.get("levels_flown")),
        "top_level": max(r.get("levels_flown") or [1])}


def render_md(doc: dict[str, Any]) -> str:
    c, g = doc["config"], doc["goals"]
    sa, sb = doc["summary"]["levels"], doc["summary"]["baseline"]
    w, h, n = c["field"]
    la, lb = c["levels"], c["baseline_levels"]

    def yes(ok: bool) -> str:
        return "met" if ok else "NOT met"

    lines = [
        f"# Flights with {la} altitude levels vs one height",
        "",
        f"{len(c['seeds'])} real flights per set (seeds {c['seeds'][0]}..{c['seeds'][-1]}, the same in both), random "
        f"{w} x {h} / {n} static targets, policy `{c['policy']}`, our SITL (PyBullet, 50 px camera, 100 deg), "
        f"companion over MAVLink/UDP in lockstep, speed-up {c['speedup']}, {c['workers']} worker process(es); "
        f"detection table {c['detection'] or 'sim/gridworld/data/detection.json (measured on this SITL camera)'}; "
        f"git {doc['git_revision']}; {doc['wall_s'] / 60:.1f} min wall. Command: `{doc['command']}`. Grid moves: the "
        "same policy on the same episode in the grid world with the same levels (and detection table).",
        "",
        f"- flight/grid moves with {la} levels: mean {_f(sa['ratio_mean'])} (goal <= {GOAL_MEAN_RATIO}: "
        f"{yes(g['ratio_mean'])}), max {_f(sa['ratio_max'])} (goal <= {GOAL_MAX_RATIO}: {yes(g['ratio_max'])}); "
        f"one height: mean {_f(sb['ratio_mean'])}, max {_f(sb['ratio_max'])}.",
        f"- targets truly found: {sa['found_pct']:.1f} % with levels ({yes(g['found_100'])}), {sb['found_pct']:.1f} % "
        f"at one height; flights stopped at the move cap: {sa['capped']} / {sb['capped']}; errors {sa['errors']} / "
        f"{sb['errors']}.",
        f"- moves per search: {_f(sa['moves_mean'])} with levels, {_f(sb['moves_mean'])} at one height (grid world "
        f"{_f(sa['grid_moves_mean'])} / {_f(sb['grid_moves_mean'])}).",
        f"- flight time per search (simulated s, first decision to last; a decision every 4 s, a climb or "
        f"descent is one): {_f(sa.get('search_s_mean'))} with levels, {_f(sb.get('search_s_mean'))} at one height "
        f"({yes(g['search_s_below'])}).",
        f"- schedule slips (a leg or a height change not settled at its decision): {sa['schedule_slips']} / "
        f"{sb['schedule_slips']}; mean NEES {_f(sa['nees_mean'])} / {_f(sb['nees_mean'])}.",
        "",
        f"| seed | moves L={la} | grid | ratio | found | search s | level changes | top level | moves L={lb} | grid "
        "| ratio | found | search s |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for p in doc["pairs"]:
        x, y = p["levels"], p["baseline"] or {}
        lines.append(f"| {p['seed']} | {'>=' if x['capped'] else ''}{x['moves']} | {x['grid_moves']} | "
                     f"{_f(x['flight_grid_ratio'])} | {x['truly_found']}/{x['targets']} | {_f(x['search_s'], 0)} | "
                     f"{x['level_changes']} | {x['top_level']} | {'>=' if y.get('capped') else ''}{y.get('moves')} | "
                     f"{y.get('grid_moves')} | {_f(y.get('flight_grid_ratio'))} | {y.get('truly_found')}/"
                     f"{y.get('targets')} | {_f(y.get('search_s'), 0)} |"
                     + (f" error: {x['error']}" if x["error"] else "") + (f" error (L={lb}): {y['error']}"
                                                                         if y.get("error") else ""))
    return "\n".join(lines) + "\n"


def _f(x: float | None, digits: int = 2) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"
