"""Supervised training on optimal decisions with k-fold cross-validation (paper Section V-C).

Read it top to bottom: `train` loads the dataset, splits it into k shuffled folds and, for each
fold, `fit_fold` trains a fresh network on the other folds, validating every epoch; the best
fold's model is kept as model.pt and the folds' held-out accuracies give Table I column (h).
Every epoch writes a checkpoint with the optimiser and RNG state, so `resume` continues an
interrupted run to exactly the weights an uninterrupted one would reach. Folds can train in
parallel processes (or on a ray cluster) and one fold can train over several GPUs with DDP.
"""

from __future__ import annotations

import math
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from provenance import atomic_write_json, stamp

from ..data import open_dataset
from ..nn.checkpoint import CheckpointError, read_checkpoint, save_checkpoint
from ..nn.config import ModelConfig
from ..nn.models import build_model
from . import distributed
from .kfold import final_path, kfold_split, partial_path, train_indices
from .metrics_log import MetricsLog, write_merged
from .plots import plot_training_curve


@dataclass(frozen=True)
class TrainConfig:
    model: str = "dualstream"
    arch: str = "small"
    epochs: int = 50
    folds: int = 10
    #: train only the first n folds (None: all k); the split is still k-fold
    run_folds: int | None = None
    batch: int = 64
    lr: float = 0.001
    momentum: float = 0.9
    optimizer: str = "sgd"  # the paper's SGD with momentum; "adam" converges faster on CPU budgets
    seed: int = 0
    device: str = "auto"
    #: CPU threads for torch (None: 1 for the small network, whose batches are too small to
    #: share between threads, torch's default for the paper's)
    threads: int | None = None
    #: cap on training samples (None: all); for quick runs
    max_samples: int | None = None
    #: processes (GPUs) per fold with DistributedDataParallel; 0: one process
    ddp: int = 0

    def __post_init__(self) -> None:
        if self.epochs < 1 or self.batch < 1 or not (math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"epochs, batch and lr must be positive and finite (got epochs {self.epochs}, "
                             f"batch {self.batch}, lr {self.lr})")
        if self.folds < 2:
            raise ValueError(f"k-fold needs folds >= 2 (got {self.folds})")
        if self.run_folds is not None and not 1 <= self.run_folds <= self.folds:
            raise ValueError(f"run_folds must be in 1..{self.folds}")
        if self.optimizer not in ("sgd", "adam"):
            raise ValueError(f"optimizer must be 'sgd' or 'adam' (got {self.optimizer!r})")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"device must be auto, cpu or cuda (got {self.device!r})")
        if self.ddp == 1 or self.ddp < 0:
            raise ValueError(f"ddp is 0 (off) or the number of processes, >= 2 (got {self.ddp})")
        if self.ddp and self.batch % self.ddp:
            raise ValueError(f"batch {self.batch} must split evenly over {self.ddp} DDP processes")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrainConfig:
        return cls(**d)


def pick_device(name: str, index: int = 0) -> torch.device:
    """CUDA when asked for or ('auto') present; `index` spreads parallel folds over GPUs."""
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda asked for, but no CUDA device is available")
    if name in ("auto", "cuda") and torch.cuda.is_available():
        return torch.device("cuda", index % torch.cuda.device_count())
    return torch.device("cpu")


@dataclass
class Data:
    """The dataset in memory, its k-fold split and what every checkpoint says about it."""

    views: torch.Tensor
    maps: torch.Tensor
    actions: torch.Tensor
    folds: list[np.ndarray]
    model_config: ModelConfig
    provenance: dict[str, Any]


def load_data(dataset: str | Path, tc: TrainConfig) -> Data:
    ds = open_dataset(dataset)
    v, m, a = ds.load()
    if tc.max_samples is not None and tc.max_samples < len(a):
        keep = np.random.default_rng(tc.seed).permutation(len(a))[: tc.max_samples]
        v, m, a = v[keep], m[keep], a[keep]
    mc = ModelConfig.for_data(v.shape[1:], m.shape[1:], int(ds.meta["config"]["n_actions"]),
                              bool(ds.meta.get("rendered")), model=tc.model, arch=tc.arch)
    meta_keys = ("config", "seed", "method", "samples", "episodes", "rendered", "git_revision")
    provenance = {
        "dataset": str(Path(dataset).resolve()),
        "dataset_meta": {k: ds.meta[k] for k in meta_keys if k in ds.meta},
        "grid_config": ds.meta["config"],
        "train_config": asdict(tc),
    }
    return Data(torch.from_numpy(v), torch.from_numpy(m), torch.from_numpy(a.astype(np.int64)),
                kfold_split(len(a), tc.folds, tc.seed), mc, provenance)


class _LossOf(nn.Module):
    """model.loss as a forward pass, so DistributedDataParallel sees (and syncs) it."""

    def __init__(self, model: nn.Module) -> None:
        super().__init__()
        self.model = model

    def forward(self, view: torch.Tensor, grid_map: torch.Tensor, target: torch.Tensor):
        return self.model.loss(view, grid_map, target)


def _optimizer(tc: TrainConfig, model: nn.Module) -> torch.optim.Optimizer:
    if tc.optimizer == "adam":
        return torch.optim.Adam(model.parameters(), lr=tc.lr)
    return torch.optim.SGD(model.parameters(), lr=tc.lr, momentum=tc.momentum)


def _batches(n: int, size: int):
    for b in range(0, n, size):
        yield slice(b, b + size)


def _rng_state(device: torch.device) -> dict[str, Any]:
    state: dict[str, Any] = {"torch": torch.get_rng_state()}
    if device.type == "cuda":
        state["cuda"] = torch.cuda.get_rng_state(device)
    return state


def _set_rng_state(state: dict[str, Any], device: torch.device) -> None:
    torch.set_rng_state(state["torch"])
    if device.type == "cuda" and "cuda" in state:
        torch.cuda.set_rng_state(state["cuda"], device)


def _check_same_run(doc: dict[str, Any], data: Data, path: Path) -> None:
    if doc.get("train_config") != data.provenance["train_config"]:
        raise CheckpointError(f"{path} was written with another training config; resume with the same options")
    if doc.get("dataset_meta") != data.provenance["dataset_meta"]:
        raise CheckpointError(f"{path} was trained on another dataset; resume with the same --dataset")


@torch.inference_mode()
def evaluate_split(model: nn.Module, data: Data, idx: torch.Tensor, device: torch.device) -> tuple[float, float]:
    model.eval()
    loss_sum, correct = 0.0, 0
    for s in _batches(len(idx), 4096):
        j = idx[s]
        loss, logits = model.loss(data.views[j].to(device), data.maps[j].to(device), data.actions[j].to(device))
        loss_sum += float(loss) * len(j)
        correct += int((logits.argmax(1).cpu() == data.actions[j]).sum())
    return loss_sum / max(len(idx), 1), correct / max(len(idx), 1)


def fit_fold(data: Data, out: Path, tc: TrainConfig, fold: int, device: torch.device, resume: bool,
             progress: bool = True, rank: int = 0, world: int = 1) -> dict[str, Any]:
    """Train a fresh network on every fold but `fold` and validate on `fold`.

    With world > 1 this is one rank of a DDP group: each global batch of `tc.batch` samples is
    split evenly over the ranks, gradients are averaged, and rank 0 alone writes files.
    """
    final, partial = final_path(out, fold), partial_path(out, fold)
    if resume and final.exists():
        doc = read_checkpoint(final)
        _check_same_run(doc, data, final)
        return doc["metrics"]

    mc = data.model_config
    val_idx = torch.from_numpy(data.folds[fold])
    train_idx = torch.from_numpy(train_indices(data.folds, fold))
    torch.manual_seed(tc.seed * 1000 + fold)
    model = build_model(mc).to(device)
    opt = _optimizer(tc, model)
    epoch, history = 0, []
    if resume and partial.exists():
        doc = read_checkpoint(partial)
        _check_same_run(doc, data, partial)
        model.load_state_dict(doc["state_dict"])
        opt.load_state_dict(doc["optimizer"])
        _set_rng_state(doc["rng"], device)
        epoch, history = doc["epoch"], doc["history"]
    net: nn.Module = _LossOf(model)
    if world > 1:
        net = nn.parallel.DistributedDataParallel(net, device_ids=[device.index] if device.type == "cuda" else None)
    log = MetricsLog(out, fold, history) if rank == 0 else None

    while epoch < tc.epochs:
        t0 = time.perf_counter()
        g = torch.Generator().manual_seed(tc.seed * 1_000_003 + fold * 1009 + epoch)
        order = train_idx[torch.randperm(len(train_idx), generator=g)]
        model.train()
        loss_sum, correct, seen = 0.0, 0, 0
        bar = tqdm(total=len(order), desc=f"fold {fold} epoch {epoch + 1}/{tc.epochs}", unit="sample",
                   unit_scale=True, disable=not progress or rank != 0, leave=False)
        for s in _batches(len(order), tc.batch):
            if len(order[s]) < world:  # a last batch too small to give every rank a sample: all skip it
                continue
            j = order[s][rank::world]  # this rank's share of the global batch
            loss, logits = net(data.views[j].to(device), data.maps[j].to(device), data.actions[j].to(device))
            value = float(loss.detach())
            if not math.isfinite(value):  # diverged: stop before a NaN model is stepped into and saved
                raise ValueError(f"training diverged: loss {value} at fold {fold}, epoch {epoch} "
                                 f"(lr {tc.lr}); nothing was saved for this epoch, try a smaller --lr")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            loss_sum += value * len(j)
            correct += int((logits.detach().argmax(1).cpu() == data.actions[j]).sum())
            seen += len(j)
            bar.update(len(j) * world)
        bar.close()
        loss_sum, correct, seen = distributed.all_reduce_sum([loss_sum, correct, seen], device)
        val_loss, val_acc = evaluate_split(model, data, val_idx, device)
        row = {"fold": fold, "epoch": epoch, "train_loss": loss_sum / seen, "train_acc": correct / seen,
               "val_loss": val_loss, "val_acc": val_acc, "seconds": time.perf_counter() - t0}
        history.append(row)
        epoch += 1
        if log is not None:
            log.write(row)
            save_checkpoint(partial, model, mc, fold=fold, epoch=epoch, history=history, optimizer=opt.state_dict(),
                            rng=_rng_state(device), seed=tc.seed, **data.provenance)

    result = {"fold": fold, "val_acc": history[-1]["val_acc"], "val_loss": history[-1]["val_loss"],
              "history": history}
    if log is not None:
        log.close()
        save_checkpoint(final, model, mc, fold=fold, epoch=epoch, seed=tc.seed, metrics=result, **data.provenance)
        partial.unlink(missing_ok=True)
    return result


def fold_job(dataset: str, out: str, tc_dict: dict[str, Any], fold: int, resume: bool) -> dict[str, Any]:
    """One fold in a worker process (local pool or ray): loads the data itself."""
    tc = TrainConfig.from_dict(tc_dict)
    torch.set_num_threads(tc.threads or 1)
    return fit_fold(load_data(dataset, tc), Path(out), tc, fold, pick_device(tc.device, fold), resume, progress=False)


def ddp_rank(rank: int, world: int, port: int, dataset: str, out: str, tc_dict: dict[str, Any], fold: int,
             resume: bool, progress: bool) -> None:
    """One DDP process of one fold (started by distributed.spawn_ddp)."""
    device = distributed.init_ddp(rank, world, port)
    try:
        tc = TrainConfig.from_dict(tc_dict)
        fit_fold(load_data(dataset, tc), Path(out), tc, fold, device, resume, progress, rank, world)
    finally:
        distributed.close_ddp()


def _default_threads(tc: TrainConfig) -> int | None:
    return tc.threads if tc.threads is not None else (1 if tc.arch == "small" else None)


def train(dataset: str | Path, out: str | Path, tc: TrainConfig, resume: bool = False, progress: bool = True,
          workers: int = 1, ray_address: str | None = None) -> dict[str, Any]:
    """k-fold training into `out`; returns the summary (also written to out/summary.json).

    workers > 1 trains folds in that many local processes; ray_address sends them to a ray
    cluster; tc.ddp > 1 trains each fold over that many GPUs (or gloo CPU processes).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    threads_before = torch.get_num_threads()
    if (n := _default_threads(tc)) is not None:
        torch.set_num_threads(n)
    try:
        data = load_data(dataset, tc)
        device = pick_device(tc.device)
        folds = list(range(tc.run_folds or tc.folds))
        if ray_address or workers > 1:
            jobs = [(str(dataset), str(out), asdict(tc), k, resume) for k in folds]
            results = distributed.run_jobs(fold_job, jobs, workers=workers, ray_address=ray_address)
        elif tc.ddp:
            results = []
            for k in folds:
                distributed.spawn_ddp(ddp_rank, tc.ddp, str(dataset), str(out), asdict(tc), k, resume, progress)
                results.append(read_checkpoint(final_path(out, k))["metrics"])
        else:
            results = []
            for k in folds:
                results.append(fit_fold(data, out, tc, k, device, resume, progress))
                write_merged(out, [r for res in results for r in res["history"]])
    finally:
        torch.set_num_threads(threads_before)

    # -- keep the best fold, summarise, plot ----------------------------------------------
    rows = [r for res in results for r in res["history"]]
    write_merged(out, rows)
    accs = np.array([r["val_acc"] for r in results])
    best = int(np.argmax(accs))
    shutil.copyfile(final_path(out, best), out / "model.pt")
    mc = data.model_config
    summary = stamp(data.provenance["grid_config"], tc.seed, model_config=mc.to_dict(), train_config=asdict(tc),
                    dataset=data.provenance["dataset_meta"],
                    folds=[{k: r[k] for k in ("fold", "val_acc", "val_loss")} for r in results], best_fold=best,
                    cv_acc_mean=float(accs.mean()), cv_acc_sd=float(accs.std()), samples=len(data.actions),
                    device=str(device))
    atomic_write_json(out / "summary.json", summary)
    plot_training_curve(rows, out / "training_curve.png", f"{mc.arch} {mc.model}: train (solid) / validation (dashed)")
    return summary
