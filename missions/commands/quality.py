"""`uavsearch quality`: every policy on every placement and motion, and the GPS table
(issue 11): results/search_quality.md + .json + plots."""

from __future__ import annotations

from pathlib import Path

import typer

from provenance import InputFileError, read_json

from .options import DETECTION, LEVELS, check_out_dir


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
        masked: bool = typer.Option(
            False, "--masked", help="Instead: the masked-fields section (issue 28): belief / oracle on random masked "
            "fields of each class vs the rectangle of the same area -> OUT/fields/masked_quality.*"),
        masked_fields: int = typer.Option(2000, "--masked-fields", min=1, help="With --masked: fields per class."),
        masked_area: int = typer.Option(100, "--masked-area", min=6, help="With --masked: searchable cells per field."),
        mask_class: list[str] | None = typer.Option(None, "--mask-class", help="With --masked: classes (default all)."),
        field: Path | None = typer.Option(
            None, "--field", help="Instead: one real field's field.json (`uavsearch field`): oracle / belief / "
            "lawnmower on --masked-fields episodes on it vs the rectangle of its area -> OUT/fields/quality_NAME.*"),
        agents: list[int] | None = typer.Option(
            None, "--agents", help="Instead: the fleet table (issue 29) for these team sizes (repeat: --agents 2 "
            "--agents 4) -> OUT/fleet_search.md + .json"),
    ) -> None:
        """Search quality table: mean moves, ratio to oracle, p90, all found %, (g)."""
        if agents:
            from policy.team.quality import run_fleet_quality, write_fleet_quality

            try:
                doc = run_fleet_quality(tuple(agents), episodes, seed, workers, tuple(setting) if setting else None)
            except ValueError as e:
                raise typer.BadParameter(str(e)) from e
            command = (f"uavsearch quality {' '.join(f'--agents {k}' for k in agents)} --episodes {episodes} "
                       f"--seed {seed} --workers {workers}")
            for p in write_fleet_quality(doc, out, command):
                typer.echo(str(p))
            return
        if field is not None:
            _field_quality(field, masked_fields, seed, workers, out)
            return
        if masked:
            from policy.evaluation.masked_quality import (
                MaskedQualityConfig,
                run_masked_quality,
                write_masked_quality,
            )
            from sim.gridworld.mask_fields import MASK_CLASSES

            check_out_dir(out)
            try:
                mq = MaskedQualityConfig(fields=masked_fields, area=masked_area, seed=seed,
                                         classes=tuple(mask_class) if mask_class else MASK_CLASSES)
            except ValueError as e:
                raise typer.BadParameter(str(e)) from e
            doc = run_masked_quality(mq, workers=workers)
            doc["command"] = (f"uavsearch quality --masked --masked-fields {masked_fields} --masked-area {masked_area}"
                              f" --seed {seed} --workers {workers}")
            for p in write_masked_quality(doc, out / "fields"):
                typer.echo(str(p))
            return
        from policy.evaluation.quality import (
            POLICIES,
            SETTINGS,
            QualityConfig,
            run_quality,
            write_quality,
        )

        check_out_dir(out)
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
            try:
                prev = read_json(reuse, "quality document")
            except InputFileError as e:
                raise typer.BadParameter(str(e), param_hint="--reuse") from None
            if not isinstance(prev, dict) or "table" not in prev or "test_seed" not in prev:
                raise typer.BadParameter(f"{reuse}: is not a quality document (no \"table\" and \"test_seed\"; "
                                         f"`uavsearch quality` writes one as quality.json)", param_hint="--reuse")
        doc = run_quality(qc, workers=workers, ray_address=ray_address, reuse=prev,
                          refresh=tuple(refresh or ()))
        for p in write_quality(doc, out):
            typer.echo(str(p))


def _field_quality(field: Path, episodes: int, seed: int, workers: int | None, out: Path) -> None:
    """`quality --field`: the masked-fields section on one real field (its reachable mask)."""
    from policy.evaluation.masked_quality import (
        MaskedQualityConfig,
        run_masked_quality,
        write_masked_quality,
    )
    from sim.gridworld import GridConfig

    from .eval import _field_grid

    check_out_dir(out)
    _, mask = _field_grid(field, GridConfig())
    name = field.resolve().parent.name if field.name == "field.json" else field.stem
    try:
        mq = MaskedQualityConfig(fields=episodes, area=int(mask.sum()), seed=seed, field_name=name,
                                 field_mask=tuple(tuple(bool(v) for v in row) for row in mask))
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--field") from e
    doc = run_masked_quality(mq, workers=workers)
    doc["command"] = f"uavsearch quality --field {field} --masked-fields {episodes} --seed {seed} --workers {workers}"
    for p in write_masked_quality(doc, out / "fields", stem=f"quality_{name}"):
        typer.echo(str(p))
