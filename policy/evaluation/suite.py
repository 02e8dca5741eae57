"""Several named policies on the same test episodes: the table the `eval` and `demo` commands
print, and the report they write."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from provenance import stamp
from sim.gridworld import GridConfig

from .paper import PAPER_TABLE1
from .report import TABLE_COLUMNS, format_cell, write_report
from .runner import evaluate

#: which paper row a policy's result sits beside, on the base case (static random targets)
BASE_CASE_ROWS = {"ns": "NS", "drqn": "DRQN", "ssn": "SSN (PT)", "dualstream": "Random (PT)"}
_CHECKPOINTED = ("dualstream", "ssn", "drqn", "searchnet")
_TRUTH = ("oracle", "cu")  # replay plans; loop detection does not apply


def paper_rows_for(cfg: GridConfig) -> dict[str, str]:
    """Policy name -> the paper's Table I row it compares with (only on the base case)."""
    base = cfg.distribution == "random" and not cfg.moving and cfg.map_variant == "spatial"
    base &= (cfg.width, cfg.height, cfg.n_targets, cfg.t_e) == (10, 10, 5, 300)
    return dict(BASE_CASE_ROWS) if base else {}


def run_eval(
    policies: list[str],
    cfg: GridConfig,
    episodes: int,
    seed: int,
    out: Path | None = None,
    progress: bool = True,
    checkpoint: Path | None = None,
    echo: bool = True,
    loop_guard: bool | None = None,
    mask: Any = None,
) -> dict[str, Any]:
    """Evaluate named policies on the same episodes; print the table (echo); write the report
    into out (JSON, Markdown, plots). Returns the JSON document. loop_guard: None = the paper's
    choice per policy (networks on static targets only), True/False forces it where it applies.
    mask: an (h, w) bool field mask (True = searchable; `uavsearch eval --field`), or None."""
    from ..baselines import make_policy

    if not policies:
        raise ValueError("name at least one policy")
    results = []
    for name in dict.fromkeys(policies):  # a name given twice is evaluated once
        kw: dict[str, Any] = {"checkpoint": checkpoint} if checkpoint is not None and name in _CHECKPOINTED else {}
        if loop_guard is not None and name not in _TRUTH:
            kw["loop_guard"] = loop_guard
        results.append(evaluate(make_policy(name, cfg, **kw), cfg, episodes, seed, progress=progress, mask=mask))
    paper = paper_rows_for(cfg)
    if out is not None:
        doc = write_report(results, out, paper)
    else:
        doc = stamp(cfg.to_dict(), seed, episodes=episodes,
                    policies={r.policy: r.columns for r in results}, paper_rows=paper)
    if mask is not None:
        doc["searchable_cells"] = int(mask.sum())
    if echo:
        print_table(doc["policies"], paper,
                    title=f"{cfg.distribution}/{cfg.motion}: {episodes} episodes, seed {seed}")
    return doc


def print_table(policies: dict[str, dict[str, Any]], paper_rows: dict[str, str] | None = None,
                title: str = "") -> None:
    """A rich table on stdout: our row per policy, the paper's figures under it where it has some."""
    from rich.console import Console
    from rich.table import Table

    paper_rows = paper_rows or {}
    t = Table(title=title, caption=" ".join(h for _, h, _ in TABLE_COLUMNS))
    t.add_column("policy", no_wrap=True)
    for _, h, _ in TABLE_COLUMNS:
        t.add_column(h.split(" ")[0] if h.startswith("(") else h, justify="right", no_wrap=True)
    for name, cols in policies.items():
        t.add_row(name, *(format_cell(cols, k, f) for k, _, f in TABLE_COLUMNS))
        row = paper_rows.get(name)
        if row in PAPER_TABLE1:
            t.add_row(f"  paper {row}", *(format_cell(PAPER_TABLE1[row], k, f) for k, _, f in TABLE_COLUMNS),
                      style="dim")
    Console(width=160).print(t)
