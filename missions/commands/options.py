"""CLI options shared by several commands, and the one place the CLI builds a GridConfig."""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from enum import StrEnum
from typing import Any

import typer

from sim.gridworld import ConfigError, GridConfig


class Dist(StrEnum):
    random = "random"
    fixed = "fixed"
    equidistant = "equidistant"
    gaussian = "gaussian"


class Motion(StrEnum):
    static = "static"
    random_walk = "random_walk"
    herd = "herd"


class MapKind(StrEnum):
    auto = "auto"
    spatial = "spatial"
    memory = "memory"
    spatiotemporal = "spatiotemporal"


DIST = typer.Option(Dist.random, "--distribution", help="Target placement P.")
MOTION = typer.Option(Motion.static, "--motion", help="Target motion.")
MAP = typer.Option(MapKind.auto, "--map", help="Map M variant (auto: spatial, or spatiotemporal for moving targets).")
WIDTH = typer.Option(10, "--width", help="Grid width (cells).")
HEIGHT = typer.Option(10, "--height", help="Grid height (cells).")
TARGETS = typer.Option(5, "--targets", help="Number of targets |R|.")
LEVELS = typer.Option(1, "--levels", min=1, max=3,
                      help="Altitude levels L (1: the paper's single height; docs/altitude.md).")
DETECTION = typer.Option(None, "--detection",
                         help="Detection table JSON for levels > 1 (default: the measured one shipped with sim).")
T_E = typer.Option(300, "--t-e", min=1, help="Move limit t_e of an episode.")


def check_out_dir(out: Any) -> None:
    """A usage error when --out names a file (it takes a directory); None or a new path passes."""
    if out is not None and out.exists() and not out.is_dir():
        raise typer.BadParameter(f"{out} is a file; --out takes a directory", param_hint="--out")


def with_levels(grid: GridConfig, levels: int = 1, detection: Any = None, t_e: int | None = None) -> GridConfig:
    """grid with altitude levels, a detection table (a JSON path) and t_e; a bad value is a
    usage error naming it. levels 1 without a table is the grid unchanged."""
    import dataclasses
    from pathlib import Path

    from sim.gridworld import DetectionTable

    try:
        table = DetectionTable.load(Path(detection)) if detection is not None else None
        return dataclasses.replace(grid, levels=levels, detection=table, t_e=grid.t_e if t_e is None else t_e)
    except ConfigError as e:
        raise typer.BadParameter(str(e)) from e


def grid_config(
    distribution: Dist, motion: Motion, map_kind: MapKind, width: int = 10, height: int = 10, targets: int = 5
) -> GridConfig:
    mp = map_kind.value
    if mp == "auto":
        mp = "spatial" if motion is Motion.static else "spatiotemporal"
    try:
        return GridConfig(
            width=width, height=height, n_targets=targets, distribution=distribution.value,
            motion=motion.value, map_variant=mp,
        )
    except ConfigError as e:
        raise typer.BadParameter(str(e)) from e


#: the grid options every grid command takes, in --help order
_GRID_PARAMS = [
    inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=kind)
    for name, default, kind in (("distribution", DIST, Dist), ("motion", MOTION, Motion), ("map_kind", MAP, MapKind),
                                ("width", WIDTH, int), ("height", HEIGHT, int), ("targets", TARGETS, int))
]


def with_grid(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Give a typer command the grid options (--distribution ... --targets); the command receives
    them checked, as one `grid: GridConfig` argument (a bad value is a clear usage error)."""
    sig = inspect.signature(fn)
    keep = [p for p in sig.parameters.values() if p.name != "grid"]

    @functools.wraps(fn)
    def command(**kw: Any) -> Any:
        grid = grid_config(*(kw.pop(p.name) for p in _GRID_PARAMS))
        return fn(grid=grid, **kw)

    command.__signature__ = sig.replace(parameters=keep + _GRID_PARAMS)  # type: ignore[attr-defined]
    return command
