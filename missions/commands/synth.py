"""`uavsearch synth`: write a ground-truth dataset of (I, M, a) samples."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

import typer

from .options import DIST, HEIGHT, MAP, MOTION, TARGETS, WIDTH, Dist, MapKind, Motion, grid_config


class Method(StrEnum):
    pt = "pt"
    cu = "cu"


def register(app: typer.Typer) -> None:
    @app.command()
    def synth(
        out: Path = typer.Option(..., "--out", help="Dataset directory to create."),
        episodes: int = typer.Option(20000, "--episodes", min=1),
        seed: int = typer.Option(0, "--seed"),
        method: Method = typer.Option(Method.pt, "--method", help="Ground truth: optimal PT or CU."),
        distribution: Dist = DIST,
        motion: Motion = MOTION,
        map_kind: MapKind = MAP,
        width: int = WIDTH,
        height: int = HEIGHT,
        targets: int = TARGETS,
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing dataset."),
    ) -> None:
        """Synthesise training samples from optimal (or CU) decisions."""
        from policy.data import open_dataset, synthesize

        cfg = grid_config(distribution, motion, map_kind, width, height, targets)
        if method is Method.cu and cfg.moving:
            raise typer.BadParameter("CU is defined for static targets; use --method pt", param_hint="--method")
        try:
            path = synthesize(cfg, episodes, seed, out, method=method.value, overwrite=overwrite)
        except FileExistsError as e:
            raise typer.BadParameter(str(e), param_hint="--out") from e
        ds = open_dataset(path)
        typer.echo(f"{path}: {len(ds)} samples from {episodes} episodes in {len(ds.meta['shards'])} shard(s)")
