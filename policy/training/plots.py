"""The paper's Fig. 6: training and validation accuracy per epoch, one colour per fold."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from provenance import atomic_open


def _axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(figsize=(6.5, 4))


def _save(fig, ax, path: Path, title: str) -> Path:
    import matplotlib.pyplot as plt

    ax.set(xlabel="epoch", ylabel="classification accuracy (%)", title=title or "training evolution")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    return Path(path)


def plot_training_curve(rows: Sequence[dict[str, Any]], path: Path, title: str = "") -> Path:
    fig, ax = _axes()
    for k in sorted({r["fold"] for r in rows}):
        rs = sorted((r for r in rows if r["fold"] == k), key=lambda r: r["epoch"])
        ep = [r["epoch"] + 1 for r in rs]
        ax.plot(ep, [100 * r["train_acc"] for r in rs], "-", color=f"C{k % 10}", alpha=0.8,
                label=f"fold {k} train")
        ax.plot(ep, [100 * r["val_acc"] for r in rs], "--", color=f"C{k % 10}", label=f"fold {k} val")
    return _save(fig, ax, path, title)


def plot_runs(runs: dict[str, Sequence[dict[str, Any]]], path: Path, title: str = "") -> Path:
    """Fig. 6 proper: several runs (e.g. datasets of 5k, 10k, 20k episodes), each run's train
    and validation accuracy averaged over its folds per epoch."""
    fig, ax = _axes()
    for i, (label, rows) in enumerate(runs.items()):
        epochs = sorted({r["epoch"] for r in rows})
        for key, style, what in (("train_acc", "-", "train"), ("val_acc", "--", "val")):
            acc = [100 * sum(r[key] for r in rows if r["epoch"] == e) / sum(1 for r in rows if r["epoch"] == e)
                   for e in epochs]
            ax.plot([e + 1 for e in epochs], acc, style, color=f"C{i % 10}", label=f"{label} {what}")
    return _save(fig, ax, path, title)
