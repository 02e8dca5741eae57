"""Training metrics: a CSV anyone can open, TensorBoard for those who use it, and the
paper's Fig. 6-style accuracy curves as a PNG."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from provenance import atomic_open

FIELDS = ("fold", "epoch", "train_loss", "train_acc", "val_loss", "val_acc", "seconds")


class MetricsLog:
    def __init__(self, out: Path, tensorboard: bool = True) -> None:
        self.csv = Path(out) / "metrics.csv"
        self.rows: list[dict[str, Any]] = []
        if self.csv.exists():
            with self.csv.open() as f:
                self.rows = [
                    {k: (int(v) if k in ("fold", "epoch") else float(v)) for k, v in r.items()}
                    for r in csv.DictReader(f)
                ]
        self._tb = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter

                self._tb = SummaryWriter(str(Path(out) / "tensorboard"))
            except ImportError:  # pragma: no cover - tensorboard is a dependency
                self._tb = None

    def truncate(self, fold: int, epoch: int) -> None:
        """Forget rows at or after (fold, epoch): a resumed run rewrites them identically."""
        self.rows = [r for r in self.rows if (r["fold"], r["epoch"]) < (fold, epoch)]

    def write(self, **row: Any) -> None:
        self.rows.append(row)
        with atomic_open(self.csv, "w") as f:
            w = csv.DictWriter(f, fieldnames=FIELDS)
            w.writeheader()
            w.writerows(self.rows)
        if self._tb is not None:
            step = row["epoch"]
            for k in ("train_loss", "train_acc", "val_loss", "val_acc"):
                self._tb.add_scalar(f"fold{row['fold']}/{k}", row[k], step)
            self._tb.flush()

    def close(self) -> None:
        if self._tb is not None:
            self._tb.close()

    def plot(self, path: Path, title: str = "") -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.5, 4))
        folds = sorted({r["fold"] for r in self.rows})
        for k in folds:
            rs = [r for r in self.rows if r["fold"] == k]
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
