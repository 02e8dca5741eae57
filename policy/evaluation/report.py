"""Evaluation output: JSON (everything, with provenance), a Markdown table with the paper's
figures side by side, the paper's Fig. 4 histogram and Fig. 2-style example paths."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open, atomic_write_json, stamp

from .paper import PAPER_TABLE1
from .runner import EvalResult

#: (key, header, format) for the Markdown table: Table I's (a)-(h) and the plain numbers.
TABLE_COLUMNS = (
    ("loop_pct", "(a) loop %", "{:.2f}"),
    ("multi_loop_pct", "(b) >1 loops %", "{:.2f}"),
    ("over_100_pct", "(c) >100 moves %", "{:.2f}"),
    ("optimal_pct", "(d) optimal %", "{:.2f}"),
    ("diff_lt_10_pct", "(e) <10 diff %", "{:.2f}"),
    ("timeout_pct", "(f) t>t_e %", "{:.2f}"),
    ("recovery_rate", "(g) recovery rate", "{}"),
    ("cv_acc", "(h) CV acc %", "{}"),
    ("mean_moves", "mean moves", "{:.1f}"),
    ("mean_ratio_to_optimal", "moves / optimal", "{:.2f}"),
    # (g) averages over the targets an episode found, so a policy that finds two targets fast and
    # then times out scores well on it; these two show what it left unfound
    ("success_pct", "all found %", "{:.1f}"),
    ("targets_per_move", "targets / move", "{:.3f}"),
)


def format_cell(row: dict[str, Any], key: str, fmt: str) -> str:
    """One table cell: '-' where a column does not apply, mean±sd for (g) and (h)."""
    if key == "recovery_rate":
        m, s = row.get("recovery_rate_mean"), row.get("recovery_rate_sd")
        return "-" if m is None else f"{m:.3f}±{s:.3f}"
    if key == "cv_acc":
        m, s = row.get("cv_acc_mean"), row.get("cv_acc_sd")
        return "-" if m is None else f"{m:.2f}±{s:.3f}"
    v = row.get(key)
    return "-" if v is None else fmt.format(v)


def markdown_table(rows: list[tuple[str, dict[str, Any], str | None]]) -> str:
    """rows: (label, our columns, paper row name or None) -> Markdown, paper line under ours."""
    head = "| row | source | " + " | ".join(h for _, h, _ in TABLE_COLUMNS) + " |"
    sep = "|" + "---|" * (len(TABLE_COLUMNS) + 2)
    lines = [head, sep]
    for label, cols, paper in rows:
        lines.append(f"| {label} | ours | " + " | ".join(format_cell(cols, k, f) for k, _, f in TABLE_COLUMNS) + " |")
        if paper and paper in PAPER_TABLE1:
            p = PAPER_TABLE1[paper]
            lines.append(f"| {label} | paper | " + " | ".join(format_cell(p, k, f) for k, _, f in TABLE_COLUMNS) + " |")
    return "\n".join(lines) + "\n"


def plot_difference_histogram(results: list[EvalResult], path: Path) -> None:
    """The paper's Fig. 4: normalised histogram of |S| - |S_GO| per policy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    cap, width = 120, 2  # beyond 120 extra moves (NS's tail, failures) pile up in the last bin
    bins = np.arange(-0.5, cap + width, width)
    for r in results:
        d = np.clip(r.moves - r.optimal, 0, cap)
        ax.hist(d, bins=bins, weights=np.full(len(d), 1.0 / len(d)), histtype="step",
                linewidth=1.6, label=r.policy)
    ax.set_yscale("log")  # the oracle's spike at 0 would flatten every other curve
    ax.set_xlabel(f"|S| - |S_GO| (moves beyond optimal, {width}-move bins; the last holds >= {cap})")
    ax.set_ylabel("fraction of episodes")
    ax.set_title(f"Solution length difference ({len(results[0].moves)} episodes)")
    ax.legend()
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)


def plot_paths(result: EvalResult, path: Path, k: int = 8) -> None:
    """Fig. 2 style: targets red, path blue, end green, unvisited black."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg = result.cfg
    k = min(k, len(result.sample_paths))
    if k == 0:
        return
    fig, axes = plt.subplots(1, k, figsize=(2.1 * k, 2.4), squeeze=False)
    for ax, traj, tg in zip(axes[0], result.sample_paths, result.sample_targets, strict=False):
        img = np.zeros((cfg.height, cfg.width, 3))
        img[traj[:, 1], traj[:, 0]] = (0.25, 0.45, 1.0)
        img[tg[:, 1], tg[:, 0]] = (1.0, 0.2, 0.2)
        img[traj[-1, 1], traj[-1, 0]] = (0.2, 0.9, 0.3)
        ax.imshow(img, interpolation="nearest")
        ax.plot(traj[:, 0], traj[:, 1], color="white", linewidth=0.8, alpha=0.7)
        ax.set_title(f"{len(traj) - 1} moves", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"{result.policy}: example episodes", fontsize=10)
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)


def write_report(
    results: list[EvalResult],
    out: Path,
    paper_rows: dict[str, str] | None = None,
    extra: dict[str, dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Write results.json, table.md, fig4_difference.png and paths_<policy>.png into out."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paper_rows = paper_rows or {}
    extra = extra or {}
    cfg = results[0].cfg
    doc = stamp(
        cfg.to_dict(),
        results[0].seed,
        episodes=len(results[0].moves),
        policies={r.policy: r.columns | extra.get(r.policy, {}) for r in results},
        paper_rows=paper_rows,
    )
    atomic_write_json(out / "results.json", doc)
    rows = [(r.policy, doc["policies"][r.policy], paper_rows.get(r.policy)) for r in results]
    md = (
        f"# Evaluation: {cfg.distribution} / {cfg.motion}, {cfg.width}x{cfg.height}, "
        f"{cfg.n_targets} targets, {len(results[0].moves)} episodes, seed {results[0].seed}\n\n"
        f"git revision `{doc['git_revision']}`\n\n" + markdown_table(rows)
    )
    with atomic_open(out / "table.md", "w") as f:
        f.write(md)
    plot_difference_histogram(results, out / "fig4_difference.png")
    for r in results:
        plot_paths(r, out / f"paths_{r.policy}.png")
    return doc
