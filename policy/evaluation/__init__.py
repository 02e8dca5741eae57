"""Table I evaluation: run policies on shared test episodes, compute every column, report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sim.gridworld import GridConfig

from .metrics import recovery_rate, table1_columns
from .paper import PAPER_TABLE1
from .report import markdown_table, write_report
from .runner import EvalResult, evaluate

#: which paper row a policy's result sits beside, on the base case (static random targets)
BASE_CASE_ROWS = {"ns": "NS", "drqn": "DRQN", "ssn": "SSN (PT)", "dualstream": "Random (PT)"}


def run_eval(
    policies: list[str],
    cfg: GridConfig,
    episodes: int,
    seed: int,
    out: Path | None = None,
    progress: bool = True,
    checkpoint: Path | None = None,
    echo: bool = True,
) -> dict[str, Any]:
    """Evaluate named policies on the same episodes; print a table; write a report to out."""
    from ..baselines import make_policy

    results = []
    for name in policies:
        kw = {"checkpoint": checkpoint} if checkpoint is not None and name in ("dualstream", "ssn", "drqn") else {}
        results.append(evaluate(make_policy(name, cfg, **kw), cfg, episodes, seed, progress=progress))
    base = cfg.distribution == "random" and not cfg.moving and cfg.map_variant == "spatial"
    paper = BASE_CASE_ROWS if base else {}
    if out is not None:
        doc = write_report(results, out, paper)
    else:
        from provenance import stamp

        doc = stamp(cfg.to_dict(), seed, episodes=episodes, policies={r.policy: r.columns for r in results})
    if echo:
        print_table(doc["policies"], title=f"{cfg.distribution}/{cfg.motion}: {episodes} episodes, seed {seed}")
    return doc


def print_table(policies: dict[str, dict[str, Any]], title: str = "") -> None:
    from rich.console import Console
    from rich.table import Table

    from .report import TABLE_COLUMNS, _fmt

    t = Table(title=title, caption=" ".join(h for _, h, _ in TABLE_COLUMNS))
    t.add_column("policy", no_wrap=True)
    for _, h, _ in TABLE_COLUMNS:
        t.add_column(h.split(" ")[0] if h.startswith("(") else h, justify="right", no_wrap=True)
    for name, cols in policies.items():
        t.add_row(name, *(_fmt(cols, k, f) for k, _, f in TABLE_COLUMNS))
    Console(stderr=True, width=160).print(t)


__all__ = [
    "BASE_CASE_ROWS", "EvalResult", "PAPER_TABLE1", "evaluate", "markdown_table", "print_table",
    "recovery_rate", "run_eval", "table1_columns", "write_report",
]
