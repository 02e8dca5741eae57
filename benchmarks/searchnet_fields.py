"""searchnet against its teacher `belief` on random masked fields of each class (issue 28):
the same episodes (test seed, never trained on) for both, mean moves and their ratio.

Why a script and not `uavsearch eval`: eval takes one field file; these are a batch of random
fields per class, drawn as `uavsearch quality --masked` draws them (random_masks(kind, area,
episodes, seed)), padded to the batch's largest box.

    PYTHONPATH=. python benchmarks/searchnet_fields.py --checkpoint CK --area 100 --targets 5 \
        --episodes 500 --out results/searchnet/fields.json
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from policy.baselines import make_policy
from policy.evaluation.runner import evaluate
from provenance import atomic_write_json, stamp
from sim.gridworld import GridConfig
from sim.gridworld.mask_fields import MASK_CLASSES, random_masks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--classes", nargs="+", default=list(MASK_CLASSES))
    ap.add_argument("--area", type=int, default=100)
    ap.add_argument("--targets", type=int, default=5)
    ap.add_argument("--episodes", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    rows = {}
    for kind in a.classes:
        masks = random_masks(kind, a.area, a.episodes, a.seed)
        cfg = GridConfig(width=masks.shape[2], height=masks.shape[1], n_targets=a.targets)
        row = {}
        for name in ("belief", "searchnet"):
            t0 = time.perf_counter()
            pol = make_policy(name, cfg, **({"checkpoint": a.checkpoint} if name == "searchnet" else {}))
            r = evaluate(pol, cfg, a.episodes, a.seed, progress=False, mask=masks)
            row[name] = {"mean_moves": float(r.moves.mean()), "all_found_pct": float(r.columns["success_pct"]),
                         "seconds": round(time.perf_counter() - t0, 1)}
        row["ratio"] = row["searchnet"]["mean_moves"] / row["belief"]["mean_moves"]
        rows[kind] = row
        print(f"{kind}: belief {row['belief']['mean_moves']:.2f}, searchnet {row['searchnet']['mean_moves']:.2f} "
              f"(all found {row['searchnet']['all_found_pct']:.1f} %), ratio {row['ratio']:.4f}", flush=True)
    mean_ratio = float(np.mean([r["ratio"] for r in rows.values()]))
    print(f"mean ratio searchnet / belief over classes: {mean_ratio:.4f}")
    if a.out:
        atomic_write_json(a.out, {**stamp(vars(a), a.seed), "rows": rows, "mean_ratio": mean_ratio})


if __name__ == "__main__":
    main()
