"""`uavsearch quality`: every policy on every placement and motion, and the GPS table
(issue 11): results/search_quality.md + .json + plots."""

from __future__ import annotations

from pathlib import Path

import typer

from .options import DETECTION, LEVELS


def register(app: typer.Typer) -> None:
    @app.command()
    def quality(
        episodes: int = typer.Option(2000, "--episodes", min=1, help="Test episodes per setting."),
        gps_episodes: int = typer.Option(500, "--gps-episodes", min=1, help="Test episodes per GPS cell."),
        seed: int = typer.Option(0, "--seed", help="Test seed (training never uses it)."),
        policy: list[str] | None = typer.Option(None, "--policy", "-p", help="Rows to run (default: all)."),
        setting: list[str] | None = typer.Option(None, "--setting", help="Settings to run (default: all)."),
        gps: bool = typer.Option(True, "--gps/--no-gps", help="Also the GPS-noise table."),
        out: Path = typer.Option(Path("results"), "--out", help="Directory for search_quality.*"),
        workers: int | None = typer.Option(1, "--workers", help="Local processes."),
        ray_address: str | None = typer.Option(None, "--ray-address", help="Fan cells out over a ray cluster."),
        reuse: Path | None = typer.Option(
            None, "--reuse", help="A previous search_quality.json: keep its measured cells, run only the others."),
        refresh: list[str] | None = typer.Option(None, "--refresh", help="With --reuse: rerun these rows anyway."),
        levels: int = LEVELS,
        detection: Path | None = DETECTION,
        t_e: int | None = typer.Option(None, "--t-e", min=1, help="Move limit t_e of every setting (default 300)."),
    ) -> None:
        """Search quality table: mean moves, ratio to oracle, p90, all found %, (g)."""
        from policy.evaluation.quality import (
            POLICIES,
            SETTINGS,
            QualityConfig,
            run_quality,
            write_quality,
        )

        if out.exists() and not out.is_dir():
            raise typer.BadParameter(f"{out} is a file; --out takes a directory", param_hint="--out")
        try:
            qc = QualityConfig(
                episodes=episodes, seed=seed, gps_episodes=gps_episodes, gps=gps,
                policies=tuple(policy) if policy else tuple(POLICIES),
                settings=tuple(setting) if setting else tuple(label for label, _ in SETTINGS),
                levels=levels, detection=None if detection is None else str(detection), t_e=t_e,
            )
        except ValueError as e:
            raise typer.BadParameter(str(e)) from e
        prev = None
        if reuse is not None:
            import json

            try:
                prev = json.loads(reuse.read_text())
            except (OSError, json.JSONDecodeError) as e:
                raise typer.BadParameter(f"cannot read {reuse}: {e}", param_hint="--reuse") from e
        doc = run_quality(qc, workers=workers, ray_address=ray_address, reuse=prev,
                          refresh=tuple(refresh or ()))
        for p in write_quality(doc, out):
            typer.echo(str(p))
