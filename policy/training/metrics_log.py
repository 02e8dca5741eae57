"""Per-epoch training metrics: a CSV anyone can open, TensorBoard for those who use it.

Each fold writes its own file (folds may train in parallel processes); `write_merged` joins
them into the run's metrics.csv. The rows also live in the fold checkpoints, so a resumed run
rewrites exactly the rows an uninterrupted one would have.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from provenance import atomic_open

FIELDS = ("fold", "epoch", "train_loss", "train_acc", "val_loss", "val_acc", "seconds")


def fold_csv(out: Path, fold: int) -> Path:
    return Path(out) / "metrics" / f"fold{fold}.csv"


def write_csv(path: Path, rows: Iterable[dict[str, Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "w") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def read_csv(path: Path) -> list[dict[str, Any]]:
    with Path(path).open() as f:
        return [{k: (int(v) if k in ("fold", "epoch") else float(v)) for k, v in r.items()}
                for r in csv.DictReader(f)]


def write_merged(out: Path, rows: Iterable[dict[str, Any]]) -> Path:
    """metrics.csv of the whole run, ordered by (fold, epoch)."""
    path = Path(out) / "metrics.csv"
    write_csv(path, sorted(rows, key=lambda r: (r["fold"], r["epoch"])))
    return path


class MetricsLog:
    """One fold's log; `rows` are those already written (from a checkpoint, when resuming)."""

    def __init__(self, out: Path, fold: int, rows: Iterable[dict[str, Any]] = (),
                 tensorboard: bool = True) -> None:
        self.path = fold_csv(out, fold)
        self.fold = fold
        self.rows: list[dict[str, Any]] = list(rows)
        self._tb = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            self._tb = SummaryWriter(str(Path(out) / "tensorboard" / f"fold{fold}"))

    def write(self, row: dict[str, Any]) -> None:
        self.rows.append(row)
        write_csv(self.path, self.rows)
        if self._tb is not None:
            for k in ("train_loss", "train_acc", "val_loss", "val_acc"):
                self._tb.add_scalar(k, row[k], row["epoch"])
            self._tb.flush()

    def close(self) -> None:
        if self._tb is not None:
            self._tb.close()
