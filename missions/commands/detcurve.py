"""`uavsearch detector-curve`: the companion's detector on the SITL's camera from each altitude
level's height, against the scene's truth: p_d(level, ring) and false alarms per cell, the
grid world's detection table (missions/detector_curve.py)."""

from __future__ import annotations

import shlex
from pathlib import Path

import typer

from .options import check_out_dir


def register(app: typer.Typer) -> None:
    @app.command("detector-curve")
    def detector_curve(
        frames: int = typer.Option(30000, "--frames", min=1, help="Frames to render in all (dealt evenly to the levels)."),
        seed: int = typer.Option(2026, "--seed", help="Seed of the fields, positions and jitter (the detector was tuned on "
                                 "seeds 1 and 2: keep those apart from measuring)."),
        camera_px: int = typer.Option(50, "--camera-px", help="The camera's resolution, pixels a side (as `sitl --camera-px`)."),
        levels: int = typer.Option(3, "--levels", min=1, max=6, help="Altitude levels 1..L (radius l, height 3.5 m (2l+1)/3)."),
        out: Path = typer.Option(Path("out/detection"), "--out", help="Directory for detection.json, report.md, curve.png."),
    ) -> None:
        """Measure p_d(level, ring) and false alarms of the companion's detector on rendered frames."""
        from missions.detector_curve import CurveConfig, measure, table, write_curve

        check_out_dir(out)
        try:
            cfg = CurveConfig(frames=frames, seed=seed, camera_px=camera_px, levels=tuple(range(1, levels + 1)))
        except ValueError as e:
            hint = "--camera-px" if "camera_px" in str(e) else "--frames" if "frames" in str(e) else None
            raise typer.BadParameter(str(e), param_hint=hint) from e
        command = (f"uavsearch detector-curve --frames {frames} --seed {seed} --camera-px {camera_px} "
                   f"--levels {levels} --out {shlex.quote(str(out))}")
        with _Progress(frames) as tick:
            counts = measure(cfg, tick)
        doc = table(cfg, counts, command=command)
        for path in write_curve(doc, out, command):
            typer.echo(str(path))
        for i, lv in enumerate(doc["levels"]):
            pd = ", ".join(f"{v:.3f}" for v in doc["p_detect"][i])
            typer.echo(f"level {lv} ({doc['height_m'][i]:g} m): p_d by ring [{pd}], false alarms "
                       f"{doc['false_alarm_per_cell'][i]:.5f} per cell")


class _Progress:
    """A rich bar on a terminal; in a log, a line every tenth of the frames."""

    def __init__(self, total: int) -> None:
        from rich.console import Console

        self.total, self.console = total, Console()
        self.bar = None

    def __enter__(self) -> _Progress:
        if self.console.is_terminal:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.bar = Progress("[bold]frames", BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                                TimeRemainingColumn(), console=self.console)
            self.bar.__enter__()
            self.task = self.bar.add_task("frames", total=self.total)
        return self

    def __call__(self, i: int) -> None:
        if self.bar is not None:
            self.bar.update(self.task, completed=i + 1)
        elif (i + 1) % max(1, self.total // 10) == 0 or i + 1 == self.total:
            print(f"detector-curve: {i + 1}/{self.total} frames", flush=True)

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.__exit__(*exc)
