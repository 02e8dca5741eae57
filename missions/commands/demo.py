"""`uavsearch demo`: the main job on embedded defaults.

1. The evaluation table: the built-in policies, the shipped networks among them, on the
   paper's base case (static random targets, 10 x 10, 5 targets), every Table I column.
2. The flight: a simulated PX4-style quadrotor (PyBullet) and the companion computer's policy
   service searching its field over MAVLink with the shipped policy; report, plot and .tlog.
"""

from __future__ import annotations

from pathlib import Path

import typer

from autopilot_bridge.service.abort import AbortAction

DEFAULT_POLICIES = ["oracle", "cu", "ns", "frontier", "lawnmower", "random", "belief"]


def register(app: typer.Typer) -> None:
    @app.command()
    def demo(
        episodes: int = typer.Option(1000, min=1, help="Test episodes per policy."),
        seed: int = typer.Option(2018, help="Seed of the test episodes and of the flight's field."),
        out: Path = typer.Option(Path("out/demo"), help="Where the report goes."),
        fly: bool = typer.Option(True, "--fly/--no-fly", help="Also fly the search on the SITL vehicle."),
        speedup: float = typer.Option(10.0, min=0.1, help="Simulation speed-up for the flight."),
        policy: str | None = typer.Option(None, "--policy", help="The policy that flies (default: the best shipped one)."),
        on_abort: AbortAction = typer.Option(
            AbortAction.rtl, "--on-abort", help="What the vehicle does when the flight fails or is interrupted."),
        agents: int = typer.Option(
            1, "--agents", min=1, max=8,
            help="2 or more: instead, N vehicles search one field together (our SITL fleet, one companion, one "
                 "shared belief; docs/fleet_flight.md): the tracks' picture and a report in OUT/fleet/."),
        width: int | None = typer.Option(None, "--width", min=2, help="The fleet's field width (--agents; default 10)."),
        height: int | None = typer.Option(None, "--height", min=2, help="The fleet's field height (--agents; default 10)."),
        targets: int | None = typer.Option(None, "--targets", min=1, help="The fleet's targets (--agents; default 5)."),
    ) -> None:
        """Evaluate the policies, then fly a search on the simulated vehicle; write a report."""
        if agents > 1:
            _fleet_demo(agents, seed, out, speedup, policy, on_abort, width, height, targets)
            return
        if (width, height, targets) != (None, None, None):
            raise typer.BadParameter("the field's size is the fleet demo's (--agents 2 or more); the lone demo "
                                     "flies the paper's 10 x 10 / 5", param_hint="--width/--height/--targets")
        from policy.baselines import known_policies
        from policy.evaluation import run_eval
        from policy.nn import shipped_checkpoint
        from sim.gridworld import GridConfig

        names = [p for p in DEFAULT_POLICIES if p in known_policies()]
        # the shipped networks; the DRQN (84 x 84 frames, most episodes run to t_e) takes minutes
        # on a CPU, so it is in results/table1_small.md and `uavsearch eval --policy drqn`
        for net in ("dualstream", "ssn", "searchnet"):
            if net in known_policies() and shipped_checkpoint(f"{net}_static_random").exists():
                names.append(net)
        run_eval(names, GridConfig(), episodes, seed, out)
        typer.echo(f"evaluation report: {out.resolve()}/table.md")
        if fly:
            from missions.flight import fly_search

            typer.echo("flying the search on the SITL vehicle (PyBullet, MAVLink, shipped policy)...")
            from missions.flight_policy import PolicyUnfit

            try:
                r = fly_search(out / "flight", seed=seed, speedup=speedup, policy=policy, on_abort=on_abort.value,
                               progress=True)
            except PolicyUnfit as e:
                raise typer.BadParameter(str(e), param_hint="--policy") from e
            found = f"{r['truly_found']}/{r['targets']} targets found (truth), {r['believed_found']} believed"
            vs_grid = ("" if r.get("flight_grid_ratio") is None else
                       f", grid world {r['grid_moves']} on the same episode: flight/grid {r['flight_grid_ratio']:.2f}")
            typer.echo(f"flight: {r['moves']} moves (optimal {r['optimal_moves']}{vs_grid}), {found}, "
                       f"{r['simulated_s']:.0f} s simulated in {r['wall_s']:.0f} s"
                       + (f"; error: {r['error']}" if r["error"] else ""))
            typer.echo(f"flight report: {(out / 'flight').resolve()}/report.md (open this first), report.json, "
                       "flight.tlog")
            code = r["outcome"]["exit_code"]
            if r["error"]:
                typer.echo(f"error: the flight stopped ({r['error']}); the vehicle was sent to {on_abort.value}: "
                           f"{r['outcome']['touchdown']}", err=True)
                raise typer.Exit(code)


def _fleet_demo(agents: int, seed: int, out: Path, speedup: float, policy: str | None, on_abort: AbortAction,
                width: int | None, height: int | None, targets: int | None) -> None:
    """`demo --agents N`: the fleet searches one field (missions.fleet_demo); OUT/fleet/report.md."""
    import sys

    from missions.fleet_demo import fly_fleet_demo
    from sim.gridworld import ConfigError, GridConfig

    if policy is not None:
        raise typer.BadParameter("a fleet flies the team belief planner (for now)", param_hint="--policy")
    if on_abort == AbortAction.hold:
        raise typer.BadParameter("a fleet lands where it is on an abort (rtl, the default, is flown as land: "
                                 "RTL would cross the others' legs)", param_hint="--on-abort")
    try:
        grid = GridConfig(width=width or 10, height=height or 10, n_targets=targets or 5)
    except ConfigError as e:
        raise typer.BadParameter(str(e)) from e
    command = "uavsearch " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["demo"] else f"uavsearch demo --agents {agents}"
    r = fly_fleet_demo(out / "fleet", agents, grid, seed, speedup, command, echo=typer.echo)
    typer.echo(f"fleet: {r['moves']} rounds (team grid world {r['grid_makespan']}), {r['truly_found']}/{r['targets']} "
               f"targets found (truth), {r['believed_found']} believed; {r['separation_refused']} setpoints refused, "
               f"least {r['min_true_distance_3d_m']} m between airborne vehicles; {r['simulated_s']:.0f} s simulated "
               f"in {r['wall_s']:.0f} s")
    typer.echo(f"fleet report: {(out / 'fleet').resolve()}/report.md (open this first), fleet.png")
    if r["outcome"] != 0:
        raise typer.Exit(int(r["outcome"]))
