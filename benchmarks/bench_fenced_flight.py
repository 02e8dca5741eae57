"""A search flight with the field's fence on the autopilot (issue 28): the same seeds flown
without a fence and with one (the field's cells + a margin, and a "pond" exclusion beside them,
inside the margin), to show the fence costs nothing: the same moves, exit 0 (no breach: the
companion's BreachWatch would have stopped the search), the preflight's fence line.

`missions.flight.fly_search` takes no fence yet (the field module will give one); here its
SearchSpec is wrapped to carry one. Our SITL (PX4 dialect, PyBullet), lockstep, speedup 10.

    nice -n 10 python benchmarks/bench_fenced_flight.py --seeds 2 --out results/fences
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

import autopilot_bridge.service.policy_service as service
from autopilot_bridge.service.fence import FencePlan
from provenance import atomic_write_json, stamp
from sim.gridworld import GridConfig, cell_to_ned


def field_fence(spec, grid: GridConfig, margin_m: float) -> FencePlan:
    """The field's cells grown by margin_m, with a 3 m square exclusion north of the field."""
    def ll(n: float, e: float) -> tuple[float, float]:
        lat, lon, _ = spec.origin.ned_to_geodetic(np.array([n, e, 0.0]))
        return lat, lon

    a, b = cell_to_ned((-0.5, -0.5)), cell_to_ned((grid.width - 0.5, grid.height - 0.5))
    (n0, n1), (e0, e1) = sorted((a[0], b[0])), sorted((a[1], b[1]))
    m = margin_m
    inclusion = [ll(n0 - m, e0 - m), ll(n0 - m, e1 + m), ll(n1 + m, e1 + m), ll(n1 + m, e0 - m)]
    pond = [ll(n1 + 1, e0 - 5), ll(n1 + 1, e0 - 2), ll(n1 + 4, e0 - 2), ll(n1 + 4, e0 - 5)]
    return FencePlan.of(inclusion, [pond])


def fly(seed: int, fenced: bool, margin_m: float, speedup: float) -> dict:
    from missions.flight import fly_search

    grid = GridConfig()
    plain = service.SearchSpec
    plans: list[FencePlan] = []

    def with_fence(*a, **kw):
        spec = plain(*a, **kw)
        plans.append(field_fence(spec, grid, margin_m))
        return replace(spec, fence=plans[-1])

    if fenced:
        service.SearchSpec = with_fence
    try:
        with tempfile.TemporaryDirectory() as out:
            rep = fly_search(Path(out), seed=seed, speedup=speedup, free_ports=True, plot=False, grid=grid)
    finally:
        service.SearchSpec = plain
    return {"seed": seed, "fence": fenced, "moves": rep["moves"], "grid_moves": rep.get("grid_moves"),
            "exit_code": rep["outcome"]["exit_code"], "error": rep.get("error"),
            "fence_vertices": len(plans[0].items()) if plans else 0}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[2])
    ap.add_argument("--margin-m", type=float, default=6.0)
    ap.add_argument("--speedup", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=Path("results/fences"))
    args = ap.parse_args()
    rows = [fly(seed, fenced, args.margin_m, args.speedup) for seed in args.seeds for fenced in (False, True)]
    for r in rows:
        print(r)
    cfg = {"seeds": args.seeds, "margin_m": args.margin_m, "speedup": args.speedup,
           "command": "python benchmarks/bench_fenced_flight.py " + " ".join(
               ["--seeds", *map(str, args.seeds), "--margin-m", str(args.margin_m)])}
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(args.out / "fenced_flight.json", stamp(cfg, args.seeds[0], kind="fenced flight", rows=rows))


if __name__ == "__main__":
    main()
