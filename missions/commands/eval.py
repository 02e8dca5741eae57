"""`uavsearch eval`: Table I's columns for any policies on shared test episodes."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import typer

from sim.gridworld import GridConfig

from .options import DETECTION, LEVELS, T_E, check_out_dir, with_grid, with_levels


def register(app: typer.Typer) -> None:
    @app.command("eval")
    @with_grid
    def eval_(
        policy: list[str] = typer.Option(["ns"], "--policy", "-p", help="Policy name; repeat for several."),
        episodes: int = typer.Option(1000, "--episodes", min=1),
        seed: int = typer.Option(0, "--seed", help="Seed of the test episodes (same for every policy)."),
        checkpoint: Path | None = typer.Option(None, "--checkpoint", help="Checkpoint for dualstream/ssn/drqn/searchnet."),
        loop_guard: bool | None = typer.Option(
            None, "--loop-guard/--no-loop-guard",
            help="Force loop detection on/off (default: the paper's choice, networks on static targets).",
        ),
        out: Path | None = typer.Option(None, "--out", help="Write results.json, table.md and plots here."),
        as_json: bool = typer.Option(False, "--json", help="Print only the JSON document on stdout."),
        levels: int = LEVELS,
        detection: Path | None = DETECTION,
        t_e: int = T_E,
        field: Path | None = typer.Option(
            None, "--field", help="A polygon field (field.json from `uavsearch field`): the grid is its grid, "
            "targets and moves on its searchable cells (--width/--height are ignored)."),
        agents: int = typer.Option(1, "--agents", min=1, help="Team size N (issue 29, docs/fleet.md): N UAVs "
                                   "in each episode; policies: belief, belief-independent, lawnmower-strips, searchnet."),
        comms_loss: float = typer.Option(0.0, "--comms-loss", help="With --agents: share of messages lost."),
        comms_delay: int = typer.Option(0, "--comms-delay", min=0, help="With --agents: message delay (steps)."),
        comms_history: int = typer.Option(1, "--comms-history", min=1,
                                          help="With --agents: observations each message repeats."),
        *,
        grid: GridConfig,
    ) -> None:
        """Evaluate policies: every Table I column, mean moves and the ratio to optimal."""
        from policy.baselines import known_policies
        from policy.evaluation import run_eval

        if agents > 1:
            if checkpoint is not None and not checkpoint.is_file():
                raise typer.BadParameter(f"no checkpoint file at {checkpoint}", param_hint="--checkpoint")
            _team_eval(policy, grid, episodes, seed, agents, comms_loss, comms_delay, comms_history, as_json,
                       checkpoint)
            return
        known = known_policies()
        unknown = [p for p in policy if p not in known]
        if unknown:
            raise typer.BadParameter(
                f"unknown policy {', '.join(unknown)}; known: {', '.join(known)}", param_hint="--policy"
            )
        check_out_dir(out)
        if checkpoint is not None and not checkpoint.is_file():
            raise typer.BadParameter(f"no checkpoint file at {checkpoint}", param_hint="--checkpoint")
        cfg, mask = grid, None
        if field is not None:
            cfg, mask = _field_grid(field, grid, echo=not as_json)
        cfg = with_levels(cfg, levels, detection, t_e)
        try:
            doc = run_eval(policy, cfg, episodes, seed, out, progress=not as_json, checkpoint=checkpoint,
                           echo=not as_json, loop_guard=loop_guard, mask=mask)
        except ValueError as e:  # e.g. a checkpoint trained for another map or action set
            raise typer.BadParameter(str(e)) from e
        if as_json:
            json.dump(doc, sys.stdout, indent=2, default=float)
            sys.stdout.write("\n")
        elif out is not None:
            typer.echo(f"report: {out.resolve()}")


def _team_eval(policy: list[str], grid: GridConfig, episodes: int, seed: int, agents: int, loss: float,
               delay: int, history: int, as_json: bool, checkpoint: Path | None = None) -> None:
    """`eval --agents N`: the team policies on the same episodes (policy.team.quality);
    checkpoint: the team searchnet's (default: the shipped one for the grid)."""
    from policy.belief.shared import CommsModel
    from policy.team.quality import run_team_eval

    try:
        doc = run_team_eval(policy, grid, episodes, seed, agents, CommsModel(delay=delay, loss=loss, history=history),
                            checkpoint)
    except ValueError as e:
        raise typer.BadParameter(str(e)) from e
    if as_json:
        json.dump(doc, sys.stdout, indent=2, default=float)
        sys.stdout.write("\n")
        return
    for name, c in doc["policies"].items():
        typer.echo(f"{name} x{agents}: mean makespan {c['mean_makespan']:.1f}, p90 {c['p90_makespan']:.0f}, "
                   f"all found {c['success_pct']:.1f} %, blocked {c['blocked_mean']:.2f}")


def _field_grid(path: Path, grid: GridConfig, echo: bool = True):
    """(GridConfig on the field's grid, its mask): the searchable cells the drone can reach, i.e.
    the largest 4-connected part (a part cut off by a no-fly zone cannot be reached without
    crossing it). A bad file is one usage error naming it."""
    import dataclasses

    import numpy as np

    from sim.field import FieldError, load_field
    from sim.gridworld import ConfigError
    from sim.gridworld.masks import largest_component

    try:
        f = load_field(str(path))
    except FieldError as e:
        raise typer.BadParameter(str(e), param_hint="--field") from e
    mask = largest_component(np.asarray(f.mask, bool))
    dropped = int(np.asarray(f.mask).sum() - mask.sum())
    try:
        cfg = dataclasses.replace(grid, width=int(f.width), height=int(f.height))
    except ConfigError as e:
        raise typer.BadParameter(f"{path}: {e}", param_hint="--field") from e
    if mask.sum() < cfg.n_targets + 1:
        raise typer.BadParameter(f"{path}: {int(mask.sum())} searchable cells cannot hold {cfg.n_targets} targets "
                                 "and the agent", param_hint="--field")
    if echo:
        typer.echo(f"{path}: grid {cfg.width} x {cfg.height}, {int(mask.sum())} searchable cells"
                   + (f" ({dropped} cut off by no-fly zones, left out)" if dropped else ""))
    return cfg, mask
