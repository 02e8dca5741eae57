"""The paper's Fig. 6: training and validation accuracy per epoch, one colour per fold."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from provenance import atomic_open


def plot_training_curve(rows: Sequence[dict[str, Any]], path: Path, title: str = "") -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4))
    for k in sorted({r["fold"] for r in rows}):
        rs = sorted((r for r in rows if r["fold"] == k), key=lambda r: r["epoch"])
        ep = [r["epoch"] + 1 for r in rs]
        ax.plot(ep, [100 * r["train_acc"] for r in rs], "-", color=f"C{k % 10}", alpha=0.8,
                label=f"fold {k} train")
        ax.plot(ep, [100 * r["val_acc"] for r in rs], "--", color=f"C{k % 10}", label=f"fold {k} val")
    ax.set(xlabel="epoch", ylabel="classification accuracy (%)", title=title or "training evolution")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    return Path(path)
