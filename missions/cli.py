"""The `uavsearch` command line. Each subcommand lives in missions/commands/<name>.py and
exposes `register(app: typer.Typer)`; this file only assembles them."""

from __future__ import annotations

import importlib

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help="UAV multi-target search stack.")

_COMMANDS = ("demo", "eval", "synth", "train", "table1", "quality", "sitl", "run", "flighttables", "field")


def _register_all() -> None:
    for name in _COMMANDS:
        try:
            mod = importlib.import_module(f"missions.commands.{name}")
        except ModuleNotFoundError as e:
            if e.name == f"missions.commands.{name}":
                continue  # not built yet
            raise
        mod.register(app)


_register_all()


def main() -> None:
    app()
