"""The `belief` planner's step (the DAgger teacher, the flight default), before and after a
revision, measured side by side: both versions decide on the same observations, alternating
which goes first, timed by thread CPU time per act(); their actions are compared on every step.
Batches of 256 episodes (the teacher's rollouts) and single episodes (the flight).

    python benchmarks/bench_planner_step.py [BEFORE (git revision, default 6eae5f2)]

BEFORE is extracted with `git archive` into a temporary directory and imported from there.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SETTINGS = [{}, {"distribution": "equidistant"}, {"motion": "herd", "distribution": "equidistant"},
            {"width": 20, "height": 20, "n_targets": 10}]


def _load(root: Path) -> dict:
    """The planner and the grid world from a source tree (fresh module objects)."""
    for k in [k for k in sys.modules if k.split(".")[0] in ("policy", "sim", "provenance")]:
        del sys.modules[k]
    sys.path.insert(0, str(root))
    try:
        from policy.base import observe
        from policy.planner import BeliefPlanner
        from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes
    finally:
        sys.path.pop(0)
    return {"planner": BeliefPlanner, "observe": observe, "world": BatchGridWorld, "cfg": GridConfig,
            "episodes": sample_episodes}


def compare(before: dict, after: dict, setting: dict, n: int) -> tuple[np.ndarray, np.ndarray, bool]:
    cfg = after["cfg"](**setting)
    prior = "model" if setting.get("distribution") == "equidistant" else None
    ts: dict[str, list[int]] = {"before": [], "after": []}
    same, k = True, 0
    for rep in range(1 if n > 1 else 20):
        seed = 11 + rep
        world = after["world"](after["episodes"](cfg, n, seed), seed)
        pols = {"before": before["planner"](prior=prior), "after": after["planner"](prior=prior)}
        for p in pols.values():
            p.reset(cfg, n, seed)
        while not world.done.all():
            obs = after["observe"](world)
            acts = {}
            for tag in (("before", "after") if k % 2 else ("after", "before")):
                t0 = time.thread_time_ns()
                acts[tag] = pols[tag].act(obs)
                ts[tag].append(time.thread_time_ns() - t0)
            same &= bool(np.array_equal(acts["before"], acts["after"]))
            world.step(acts["after"])
            k += 1
    return np.array(ts["before"]) / 1e6, np.array(ts["after"]) / 1e6, same


def main() -> None:
    rev = sys.argv[1] if len(sys.argv) > 1 else "6eae5f2"
    with tempfile.TemporaryDirectory() as tmp:
        got = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "policy", "sim", "provenance"],
                             capture_output=True)
        if got.returncode != 0:  # e.g. a shallow clone: nothing to compare against, say so
            print(f"revision {rev} is not in this checkout ({got.stderr.decode().strip()}); "
                  "give one that is: python benchmarks/bench_planner_step.py REV")
            return
        archive = got.stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        before = _load(Path(tmp))
        after = _load(ROOT)
        print(f"belief planner act(), ms of thread CPU time per step, {rev} (before) vs this tree (after), "
              f"interleaved on the same observations; load average {os.getloadavg()[0]:.2f}")
        print(f"{'setting':<38}{'batch':>6}{'steps':>7}{'before':>9}{'after':>9}{'ratio':>7}  same actions")
        for setting in SETTINGS:
            for n in (256, 1):
                b, a, same = compare(before, after, setting, n)
                name = ",".join(f"{k}={v}" for k, v in setting.items()) or "static random 10x10"
                print(f"{name:<38}{n:>6}{len(a):>7}{b.mean():9.3f}{a.mean():9.3f}{a.mean() / b.mean():7.2f}  {same}")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
