"""Search quality on masked fields (issue 28): for each class of random masked field (convex,
L, holes, strips; sim.gridworld.mask_fields), `fields` random fields of `area` searchable
cells, one episode each, and the rectangle of the same searchable area: each policy's ratio
of mean moves to the (exact) oracle's on the masked fields against its ratio on the rectangle.
The goal: `belief`'s within 5 % of its rectangle ratio; lawnmower beside, for comparison.

Seeds: field i of a class is drawn from (seed, i) via random_masks (the class's own stream),
the episodes from sample_episodes(cfg, fields, seed, masks); the rectangle's episodes from
sample_episodes(cfg, fields, seed). Every policy meets the same episodes.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig
from sim.gridworld.mask_fields import MASK_CLASSES

from .runner import evaluate

RECTANGLE = "rectangle"
ORIENTATIONS: tuple[str, ...] = ("aligned", "rotated")
GOAL = 0.05


@dataclass(frozen=True)
class MaskedQualityConfig:
    fields: int = 2000
    area: int = 100
    targets: int = 5
    seed: int = 0
    policies: tuple[str, ...] = ("oracle", "belief", "lawnmower")
    classes: tuple[str, ...] = MASK_CLASSES
    #: "aligned": the field laid along the grid (how `uavsearch field` lays it by default);
    #: "rotated": at a random angle to the grid (staircase edges)
    orientations: tuple[str, ...] = ORIENTATIONS
    #: instead of the random classes: one real field (`uavsearch quality --field`): its name and
    #: its mask (rows of searchable cells, the part the drone can reach), every episode on it;
    #: `area` is then its searchable cells
    field_name: str | None = None
    field_mask: tuple[tuple[bool, ...], ...] | None = None

    def __post_init__(self) -> None:
        if self.fields < 1:
            raise ValueError(f"fields must be >= 1 (got {self.fields})")
        if not self.targets + 1 <= self.area:
            raise ValueError(f"area must hold the targets and the agent (got area {self.area}, {self.targets} targets)")
        bad = [c for c in self.classes if c not in MASK_CLASSES]
        if bad:
            raise ValueError(f"unknown mask class(es) {bad}; known: {', '.join(MASK_CLASSES)}")
        bad = [o for o in self.orientations if o not in ORIENTATIONS]
        if bad:
            raise ValueError(f"unknown orientation(s) {bad}; known: {', '.join(ORIENTATIONS)}")
        if (self.field_name is None) != (self.field_mask is None):
            raise ValueError("a real field needs its name and its mask")
        if self.field_mask is not None and int(np.asarray(self.field_mask, bool).sum()) != self.area:
            raise ValueError(f"area must be the field's searchable cells ({int(np.asarray(self.field_mask).sum())}, "
                             f"got {self.area})")
        if "oracle" not in self.policies:
            raise ValueError("the masked-fields section needs the oracle row (ratios are to it)")

    @property
    def rectangle(self) -> tuple[int, int]:
        """(width, height) of the rectangle of the same area: the most nearly square one; where
        that is longer than twice its width (a real field's 542 cells: 271 x 2, a strip), the
        nearest square-ish rectangle instead (542: 24 x 23 = 552, within a side's length)."""
        h = int(np.sqrt(self.area))
        while self.area % h:
            h -= 1
        if self.area // h <= 2 * h:
            return self.area // h, h
        h = int(round(np.sqrt(self.area)))
        return int(round(self.area / h)), h


def masked_task(label: str, qc_dict: dict[str, Any]) -> dict[str, Any]:
    """One class (or the rectangle): every policy's summary on its fields. Module-level, plain
    arguments, so fan_out can ship it to a process."""
    from sim.gridworld.mask_fields import random_masks

    from ..baselines import make_policy

    qc = MaskedQualityConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in qc_dict.items()})
    t0 = time.perf_counter()
    if label == RECTANGLE:
        w, h = qc.rectangle
        mask = None
    elif qc.field_mask is not None:  # one real field: every episode on its mask
        one = np.asarray(qc.field_mask, bool)
        mask = np.repeat(one[None], qc.fields, axis=0)
        h, w = one.shape
    else:
        kind, orientation = label.split(", ")
        mask = random_masks(kind, qc.area, qc.fields, qc.seed, rotated=orientation == "rotated")
        h, w = mask.shape[1:]
    cfg = GridConfig(width=w, height=h, n_targets=qc.targets)
    out: dict[str, Any] = {"grid": [w, h], "fields_s": round(time.perf_counter() - t0, 1), "rows": {}}
    for name in qc.policies:
        t1 = time.perf_counter()
        r = evaluate(make_policy(name, cfg), cfg, qc.fields, qc.seed, progress=False, mask=mask)
        out["rows"][name] = {
            "mean_moves": float(r.moves.mean()),
            "p90_moves": float(np.percentile(r.moves, 90)),
            "all_found_pct": float(r.columns["success_pct"]),
            "mean_optimal_moves": float(r.optimal.mean()),
            "episodes": int(len(r.moves)),
            "seconds": round(time.perf_counter() - t1, 1),
        }
    if mask is not None:
        out["masked_share_pct"] = float(100 * (1 - mask.mean()))
    return out


def run_masked_quality(qc: MaskedQualityConfig, workers: int | None = 1) -> dict[str, Any]:
    from ..fanout import fan_out

    t0 = time.perf_counter()
    labels = [RECTANGLE, *(f"{k}, {o}" for o in qc.orientations for k in qc.classes)] if qc.field_mask is None \
        else [RECTANGLE, f"field {qc.field_name}"]
    cfg_dict = asdict(qc)
    results = fan_out(masked_task, [(label, cfg_dict) for label in labels], workers=workers)
    table = dict(zip(labels, results, strict=True))
    rect = table[RECTANGLE]["rows"]
    for label in labels:
        rows = table[label]["rows"]
        oracle = rows["oracle"]["mean_moves"]
        for name, c in rows.items():
            c["ratio"] = c["mean_moves"] / oracle
            c["vs_rectangle"] = c["ratio"] / (rect[name]["mean_moves"] / rect["oracle"]["mean_moves"]) - 1.0
    return stamp({"masked_quality": cfg_dict}, qc.seed, fields=qc.fields, table=table,
                 command=f"uavsearch quality --masked --masked-fields {qc.fields}",
                 seconds=round(time.perf_counter() - t0, 1), goal=f"belief ratio within {GOAL:.0%} of the rectangle's")


def markdown(doc: dict[str, Any]) -> str:
    qc = doc["config"]["masked_quality"]
    w, h = doc["table"][RECTANGLE]["grid"]
    if qc.get("field_name"):
        what = (f"`{doc['command']}`: {doc['fields']} episodes on the real field {qc['field_name']} "
                f"({qc['area']} searchable cells the drone can reach; `uavsearch field` laid its grid), "
                f"{qc['targets']} static targets placed uniformly on them; the rectangle is {w} x {h} "
                f"(the same searchable area, or the nearest square-ish one where that is a strip), {doc['fields']} episodes. git `{doc['git_revision']}`, "
                f"{doc['created_utc']}, {doc['seconds']} s.")
    else:
        what = (f"`{doc['command']}`: per class {doc['fields']} random masked fields of {qc['area']} searchable "
                f"cells (sim.gridworld.mask_fields, field i from seed ({qc['seed']}, i)), one episode each, "
                "each class laid along the grid (`aligned`: the polygon's minimum-area rectangle or its arms along "
                "the grid's axes, as `uavsearch field` lays its grid by default) and at a random angle to it "
                "(`rotated`: staircase edges); "
                f"{qc['targets']} static targets placed uniformly on searchable cells; the rectangle is {w} x {h} "
                f"(the same searchable area), {doc['fields']} episodes. git `{doc['git_revision']}`, "
                f"{doc['created_utc']}, {doc['seconds']} s.")
    lines = [
        "# Search quality on masked fields (issue 28)", "", what, "",
        "Ratio: mean moves / the oracle's (Held-Karp on BFS path lengths around the holes: exact). "
        "vs rectangle: the ratio over the same policy's ratio on the rectangle, minus 1. "
        f"Goal: `belief` within {GOAL:.0%} (at most {GOAL:.0%} above; a lower ratio is better).", "",
        "| field | grid (padded) | masked % | policy | mean moves | / oracle | vs rectangle | p90 | all found % |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, cell in doc["table"].items():
        gw, gh = cell["grid"]
        share = f"{cell['masked_share_pct']:.0f}" if "masked_share_pct" in cell else "0"
        for name, c in cell["rows"].items():
            lines.append(f"| {label} | {gw} x {gh} | {share} | {name} | {c['mean_moves']:.1f} | {c['ratio']:.3f} | "
                         f"{c['vs_rectangle']:+.1%} | {c['p90_moves']:.0f} | {c['all_found_pct']:.1f} |")
    lines.append("")
    met = [label for label, cell in doc["table"].items() if label != RECTANGLE and "belief" in cell["rows"]
           and cell["rows"]["belief"]["vs_rectangle"] <= GOAL]
    missed = [label for label, cell in doc["table"].items() if label != RECTANGLE and "belief" in cell["rows"]
              and cell["rows"]["belief"]["vs_rectangle"] > GOAL]
    lines += [f"`belief`'s ratio at most {GOAL:.0%} above its rectangle ratio (lower is better): "
              f"{'; '.join(met) or 'none'}. Above: {'; '.join(missed) or 'none'}.", ""]
    return "\n".join(lines)


def write_masked_quality(doc: dict[str, Any], out: Path, stem: str = "masked_quality") -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    js, md = out / f"{stem}.json", out / f"{stem}.md"
    atomic_write_json(js, doc)
    with atomic_open(md, "w") as f:
        f.write(markdown(doc))
    return [js, md]
