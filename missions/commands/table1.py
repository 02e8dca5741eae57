"""`uavsearch table1`: every row of the paper's Table I, synthesised, trained and evaluated."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

import typer


class ScaleName(StrEnum):
    small = "small"
    full = "full"
    smoke = "smoke"


def register(app: typer.Typer) -> None:
    @app.command()
    def table1(
        scale: ScaleName = typer.Option(ScaleName.small, "--scale", help="small: 2 CPU cores, < 30 min; full: the paper's protocol; smoke: a pipeline check."),
        out: Path = typer.Option(Path("results"), "--out"),
        seed: int = typer.Option(0, "--seed"),
        only: list[str] | None = typer.Option(None, "--only", help="Run only these rows (paper labels)."),
        workers: int | None = typer.Option(None, "--workers", help="Local processes (default: CPU count)."),
        ray_address: str | None = typer.Option(None, "--ray-address", help="Fan rows out over a ray cluster."),
        drqn_checkpoint: Path | None = typer.Option(
            None, "--drqn-checkpoint",
            help="Test this DRQN. Default: full trains one (20k episodes, resumable), small tests the shipped one."),
    ) -> None:
        """Reproduce Table I with the paper's figures side by side (Markdown + JSON + Fig. 4)."""
        from missions.table1 import SCALES, run_table1
        from policy.nn import shipped_checkpoint

        ckpt = drqn_checkpoint
        if ckpt is not None:  # a bad file is said now, not after the other rows ran for an hour
            from policy.drqn.train import load_drqn
            from policy.nn.checkpoint import CheckpointError

            try:
                load_drqn(ckpt)
            except CheckpointError as e:
                raise typer.BadParameter(str(e), param_hint="--drqn-checkpoint") from None
        if ckpt is None and not SCALES[scale.value].drqn_episodes:
            ckpt = shipped_checkpoint("drqn_static_random")
        try:
            run_table1(scale.value, out, seed, only, workers, ray_address, ckpt)
        except ValueError as e:
            raise typer.BadParameter(str(e)) from e
        typer.echo(f"{out / f'table1_{scale.value}.md'}")
