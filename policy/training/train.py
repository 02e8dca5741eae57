"""Supervised training on optimal decisions with k-fold cross-validation (paper Section V-C).

Read it top to bottom: load the dataset, split it into k shuffled folds, and for each fold
train a fresh network on the other folds, validating every epoch; keep the best fold's model.
A checkpoint after every epoch holds the optimiser and RNG state, so `resume` continues an
interrupted run to exactly the weights an uninterrupted one would reach.
"""

from __future__ import annotations

import json
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from provenance import atomic_write_json, stamp

from ..data import open_dataset
from ..nn.checkpoint import read_checkpoint, save_checkpoint
from ..nn.config import ModelConfig
from ..nn.models import build_model
from .log import MetricsLog


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
    threads: int | None = None
    #: cap on training samples (None: all); for quick runs
    max_samples: int | None = None

    def __post_init__(self) -> None:
        if self.epochs < 1 or self.batch < 1 or self.lr <= 0:
            raise ValueError("epochs, batch and lr must be positive")
        if self.folds < 2:
            raise ValueError(f"k-fold needs folds >= 2 (got {self.folds})")
        if self.run_folds is not None and not 1 <= self.run_folds <= self.folds:
            raise ValueError(f"run_folds must be in 1..{self.folds}")
        if self.optimizer not in ("sgd", "adam"):
            raise ValueError(f"optimizer must be 'sgd' or 'adam' (got {self.optimizer!r})")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"device must be auto, cpu or cuda (got {self.device!r})")


def pick_device(name: str) -> torch.device:
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda asked for, but no CUDA device is available")
    return torch.device("cuda" if name in ("auto", "cuda") and torch.cuda.is_available() else "cpu")


def _optimizer(tc: TrainConfig, model: torch.nn.Module) -> torch.optim.Optimizer:
    if tc.optimizer == "adam":
        return torch.optim.Adam(model.parameters(), lr=tc.lr)
    return torch.optim.SGD(model.parameters(), lr=tc.lr, momentum=tc.momentum)


def _batches(n: int, size: int):
    for b in range(0, n, size):
        yield slice(b, b + size)


@torch.inference_mode()
def evaluate_split(model, views, maps, actions, idx, device) -> tuple[float, float]:
    model.eval()
    loss_sum, correct = 0.0, 0
    for s in _batches(len(idx), 4096):
        j = idx[s]
        loss, logits = model.loss(views[j].to(device), maps[j].to(device), actions[j].to(device))
        loss_sum += float(loss) * len(j)
        correct += int((logits.argmax(1).cpu() == actions[j]).sum())
    return loss_sum / max(len(idx), 1), correct / max(len(idx), 1)


def train(dataset: str | Path, out: str | Path, tc: TrainConfig, resume: bool = False,
          progress: bool = True) -> dict[str, Any]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if tc.threads:
        torch.set_num_threads(tc.threads)
    device = pick_device(tc.device)

    # -- data --------------------------------------------------------------------------
    ds = open_dataset(dataset)
    v_np, m_np, a_np = ds.load()
    if tc.max_samples is not None and tc.max_samples < len(a_np):
        keep = np.random.default_rng(tc.seed).permutation(len(a_np))[: tc.max_samples]
        v_np, m_np, a_np = v_np[keep], m_np[keep], a_np[keep]
    views, maps, actions = torch.from_numpy(v_np), torch.from_numpy(m_np), torch.from_numpy(a_np)
    mc = ModelConfig.for_data(
        v_np.shape[1:], m_np.shape[1:], int(ds.meta["config"]["n_actions"]),
        bool(ds.meta.get("rendered")), model=tc.model, arch=tc.arch,
    )
    folds = np.array_split(np.random.default_rng([tc.seed, 0xF01D]).permutation(len(a_np)), tc.folds)
    n_run = tc.run_folds or tc.folds
    provenance = {
        "dataset": str(Path(dataset).resolve()), "dataset_meta": {k: ds.meta[k] for k in ("config", "seed", "method", "samples", "git_revision") if k in ds.meta},
        "grid_config": ds.meta["config"], "train_config": asdict(tc),
    }

    # -- resume ------------------------------------------------------------------------
    log = MetricsLog(out)
    fold, epoch, results = 0, 0, []
    model = opt = None
    last = out / "last.pt"
    if resume and last.exists():
        doc = read_checkpoint(last)
        if doc.get("train_config") != asdict(tc):
            raise ValueError(f"{last} was written with another training config; resume with the same options")
        fold, epoch, results = doc["fold"], doc["epoch"], doc["results"]
        if epoch > 0:
            model = build_model(mc).to(device)
            model.load_state_dict(doc["state_dict"])
            opt = _optimizer(tc, model)
            opt.load_state_dict(doc["optimizer"])
            torch.set_rng_state(doc["torch_rng"])
    log.truncate(fold, epoch)

    # -- k-fold training ----------------------------------------------------------------
    while fold < n_run:
        val_idx = torch.from_numpy(folds[fold])
        train_idx = torch.from_numpy(np.concatenate([f for i, f in enumerate(folds) if i != fold]))
        if model is None:
            torch.manual_seed(tc.seed * 1000 + fold)
            model = build_model(mc).to(device)
            opt = _optimizer(tc, model)
        while epoch < tc.epochs:
            t0 = time.perf_counter()
            g = torch.Generator().manual_seed(tc.seed * 1_000_003 + fold * 1009 + epoch)
            order = train_idx[torch.randperm(len(train_idx), generator=g)]
            model.train()
            loss_sum, correct = 0.0, 0
            bar = tqdm(total=len(order), desc=f"fold {fold} epoch {epoch + 1}/{tc.epochs}", unit="sample",
                       unit_scale=True, disable=not progress, leave=False)
            for s in _batches(len(order), tc.batch):
                j = order[s]
                loss, logits = model.loss(views[j].to(device), maps[j].to(device), actions[j].to(device))
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                loss_sum += float(loss.detach()) * len(j)
                correct += int((logits.detach().argmax(1).cpu() == actions[j]).sum())
                bar.update(len(j))
            bar.close()
            val_loss, val_acc = evaluate_split(model, views, maps, actions, val_idx, device)
            log.write(fold=fold, epoch=epoch, train_loss=loss_sum / len(order), train_acc=correct / len(order),
                      val_loss=val_loss, val_acc=val_acc, seconds=time.perf_counter() - t0)
            epoch += 1
            save_checkpoint(last, model, mc, fold=fold, epoch=epoch, results=results, optimizer=opt.state_dict(),
                            torch_rng=torch.get_rng_state(), seed=tc.seed, **provenance)
        results.append({"fold": fold, "val_acc": val_acc, "val_loss": val_loss})
        save_checkpoint(out / f"fold{fold}.pt", model, mc, fold=fold, epoch=epoch, seed=tc.seed,
                        metrics=results[-1], **provenance)
        fold, epoch, model, opt = fold + 1, 0, None, None
        save_checkpoint(last, build_model(mc), mc, fold=fold, epoch=0, results=results, optimizer={},
                        torch_rng=torch.get_rng_state(), seed=tc.seed, **provenance)

    # -- keep the best fold --------------------------------------------------------------
    accs = np.array([r["val_acc"] for r in results])
    best = int(np.argmax(accs))
    shutil.copyfile(out / f"fold{best}.pt", out / "model.pt")
    summary = stamp(provenance["grid_config"], tc.seed, model_config=mc.to_dict(), train_config=asdict(tc),
                    dataset=provenance["dataset_meta"], folds=results, best_fold=best,
                    cv_acc_mean=float(accs.mean()), cv_acc_sd=float(accs.std()), samples=int(len(a_np)),
                    device=str(device))
    atomic_write_json(out / "summary.json", summary)
    log.plot(out / "training_curve.png", f"{mc.arch} {mc.model}: train (solid) / validation (dashed)")
    log.close()
    return json.loads(json.dumps(summary, default=str))
