"""`uavsearch train`: fit the dual-stream network (or SSN) on a dataset with k-fold CV."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

import typer


class Model(StrEnum):
    dualstream = "dualstream"
    ssn = "ssn"


class Arch(StrEnum):
    small = "small"
    paper = "paper"


class Opt(StrEnum):
    sgd = "sgd"
    adam = "adam"


class Device(StrEnum):
    auto = "auto"
    cpu = "cpu"
    cuda = "cuda"


def register(app: typer.Typer) -> None:
    @app.command()
    def train(
        dataset: Path = typer.Option(..., "--dataset", help="Directory written by `uavsearch synth`."),
        out: Path = typer.Option(..., "--out", help="Run directory (checkpoints, metrics, plots)."),
        model: Model = typer.Option(Model.dualstream, "--model"),
        arch: Arch = typer.Option(Arch.small, "--arch", help="small (default) or the paper's layer sizes."),
        epochs: int = typer.Option(50, "--epochs", min=1),
        folds: int = typer.Option(10, "--folds", min=2, help="k of k-fold cross-validation."),
        run_folds: int | None = typer.Option(None, "--run-folds", min=1, help="Train only the first n folds."),
        batch: int = typer.Option(64, "--batch", min=1),
        lr: float = typer.Option(0.001, "--lr"),
        optimizer: Opt = typer.Option(Opt.sgd, "--optimizer", help="sgd (momentum 0.9, the paper) or adam."),
        seed: int = typer.Option(0, "--seed"),
        device: Device = typer.Option(Device.auto, "--device"),
        resume: bool = typer.Option(False, "--resume", help="Continue an interrupted run in --out."),
        threads: int | None = typer.Option(None, "--threads", min=1,
                                           help="torch CPU threads (default: 1 for small, torch's for paper)."),
        workers: int = typer.Option(1, "--workers", min=1, help="Train folds in this many local processes."),
        ray_address: str | None = typer.Option(None, "--ray-address",
                                               help="Send folds to this ray cluster (dataset on a shared path)."),
        ddp: int = typer.Option(0, "--ddp", min=0, help="DDP processes (GPUs) per fold; 0: off."),
    ) -> None:
        """Train on optimal decisions; the best fold's model is written to OUT/model.pt."""
        from policy.data import DatasetError
        from policy.training import TrainConfig
        from policy.training import train as run

        try:
            tc = TrainConfig(model=model.value, arch=arch.value, epochs=epochs, folds=folds, run_folds=run_folds,
                             batch=batch, lr=lr, optimizer=optimizer.value, seed=seed, device=device.value,
                             threads=threads, ddp=ddp)
            summary = run(dataset, out, tc, resume=resume, workers=workers, ray_address=ray_address)
        except DatasetError as e:
            raise typer.BadParameter(str(e), param_hint="--dataset") from e
        except (ValueError, RuntimeError) as e:  # CheckpointError is a ValueError
            raise typer.BadParameter(str(e)) from e
        typer.echo(
            f"{out}/model.pt: CV accuracy {100 * summary['cv_acc_mean']:.2f} ± {100 * summary['cv_acc_sd']:.2f} % "
            f"over {len(summary['folds'])} fold(s); best fold {summary['best_fold']}"
        )
