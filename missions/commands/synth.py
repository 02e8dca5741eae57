"""`uavsearch synth`: write a ground-truth dataset of (I, M, a) samples."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

import typer

from sim.gridworld import GridConfig

from .options import with_grid


class Method(StrEnum):
    pt = "pt"
    cu = "cu"


def register(app: typer.Typer) -> None:
    @app.command()
    @with_grid
    def synth(
        out: Path = typer.Option(..., "--out", help="Dataset directory to create."),
        episodes: int = typer.Option(20000, "--episodes", min=1),
        seed: int = typer.Option(0, "--seed"),
        method: Method = typer.Option(Method.pt, "--method", help="Ground truth: optimal PT or CU."),
        rendered: bool = typer.Option(
            False, "--rendered", help="Views from the simulated 50x50 camera (the paper's +S)."
        ),
        shard_size: int = typer.Option(100_000, "--shard-size", min=1, help="Samples per shard."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing dataset."),
        progress: bool = typer.Option(True, "--progress/--quiet", help="Show a progress bar."),
        *,
        grid: GridConfig,
    ) -> None:
        """Synthesise training samples from optimal (or CU) decisions."""
        from policy.data import open_dataset, synthesize

        cfg = grid
        if method is Method.cu and cfg.moving:
            raise typer.BadParameter(
                "CU is defined for static targets; use --method pt", param_hint="--method"
            )
        if (out / "meta.json").exists() and not overwrite:
            raise typer.BadParameter(f"{out} already holds a dataset; --overwrite replaces it",
                                     param_hint="--out")
        view_fn, renderer = None, None
        if rendered:
            from sim.vehicle import ViewRenderer

            renderer = ViewRenderer(cfg.width, cfg.height, cfg.n_targets, image=50, seed=seed)

            def view_fn(world):  # noqa: ANN001, ANN202 - BatchGridWorld -> (n, 3, 50, 50) uint8
                return renderer.render_views(world.targets(), world.agent, cfg.width, cfg.height)

        try:
            path = synthesize(cfg, episodes, seed, out, method=method.value, shard_size=shard_size,
                              view_fn=view_fn, progress=progress, overwrite=overwrite)
        except FileExistsError as e:
            raise typer.BadParameter(str(e), param_hint="--out") from e
        finally:
            if renderer is not None:
                renderer.close()
        ds = open_dataset(path)
        typer.echo(f"{path}: {len(ds)} samples from {episodes} episodes in "
                   f"{len(ds.meta['shards'])} shard(s)")
