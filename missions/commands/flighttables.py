"""`uavsearch flight-table` and `uavsearch gps-table`: real flights, many seeds, in parallel
processes (each flight its own SITL and ports): the flight vs the grid world, and the search
under GPS noise. Results with provenance in results/."""

from __future__ import annotations

from pathlib import Path

import typer

from missions.commands.options import DETECTION, LEVELS, with_levels
from sim.gridworld import GridConfig


def _seeds(first: int, n: int) -> list[int]:
    if n < 1:
        raise typer.BadParameter(f"{n}: need at least one seed", param_hint="--seeds")
    return list(range(first, first + n))


def register(app: typer.Typer) -> None:
    @app.command("flight-table")
    def flight_table(
        seeds: int = typer.Option(20, "--seeds", help="How many seeds (flights)."),
        first_seed: int = typer.Option(0, "--first-seed"),
        workers: int = typer.Option(2, "--workers", min=1, help="Flights at once (processes)."),
        speedup: float = typer.Option(10.0, "--speedup", min=0.5, help="Simulation speed-up of each flight."),
        policy: str | None = typer.Option(None, "--policy", help="Registered policy (default: the flight default)."),
        max_moves: int | None = typer.Option(None, "--max-moves", min=1, help="Cap per flight (default: t_e)."),
        out: Path = typer.Option(Path("results"), "--out"),
        autopilot: str = typer.Option(
            "ours", "--autopilot", help="Who flies: ours (our SITL vehicle), or the real ardupilot / px4 SITL binary "
                                        "($ARDUPILOT_SITL / $PX4_SITL) on our world's physics."),
        camera: str = typer.Option(
            "mavlink", "--camera", help="Frames from the MAVLink camera component (mavlink) or the SITL's RTP/H.264 "
                                        "stream decoded by PyAV (video; our vehicle only)."),
        width: int | None = typer.Option(None, "--width", min=2, help="Field width (cells) (default: 10)."),
        height: int | None = typer.Option(None, "--height", min=2, help="Field height (cells) (default: 10)."),
        targets: int | None = typer.Option(None, "--targets", min=1, help="Targets |R| (default: 5)."),
        levels: int = LEVELS,
        detection: Path | None = DETECTION,
        baseline_levels: int | None = typer.Option(
            None, "--baseline-levels", min=1, max=3,
            help="Also fly the same seeds with this many levels (e.g. 1) and write OUT/flight_levels.md side by "
                 "side (docs/altitude.md)."),
        field: Path | None = typer.Option(
            None, "--field", help="A real field's field.json (`uavsearch field`): every flight searches inside its "
                                  "polygon (our vehicle), checked for setpoints, breaches and true positions off it."),
        agents: int = typer.Option(
            1, "--agents", min=1, max=8,
            help="Fly a fleet of N vehicles on one field from one companion (docs/fleet_flight.md): makespan "
                 "against the team grid world's -> OUT/fleet_flights.{md,json} (default field 20 x 20 / 10)."),
    ) -> None:
        """Fly the same policy on >= 20 seeds and compare each flight's moves with the grid world's."""
        import sys

        from missions.flight_table import flight_vs_grid

        if agents > 1:
            _fleet_table(agents, seeds, first_seed, speedup, out, width, height, targets, autopilot, camera, levels,
                         field, policy)
            return

        if field is not None:
            from missions.field_run import load_polygon

            if autopilot != "ours":
                raise typer.BadParameter("a real field is flown by our vehicle (--autopilot ours)", param_hint="--field")
            try:
                load_polygon(field)
            except ValueError as e:
                raise typer.BadParameter(str(e), param_hint="--field") from e

        if autopilot not in ("ours", "ardupilot", "px4"):
            raise typer.BadParameter(f"{autopilot!r}: expected ours, ardupilot or px4", param_hint="--autopilot")
        if camera not in ("mavlink", "video") or (camera == "video" and autopilot != "ours"):
            raise typer.BadParameter(f"{camera!r}: mavlink, or video with --autopilot ours", param_hint="--camera")
        size = None
        if (width, height, targets) != (None, None, None):
            if field is not None:
                raise typer.BadParameter("a real field sets its own grid: no --width/--height/--targets with it",
                                         param_hint="--field")
            size = (width or 10, height or 10, targets or 5)
        if levels > 1 or detection is not None or baseline_levels is not None:
            if camera != "mavlink":  # our SITL, ArduCopter and PX4 alike: the MAVLink camera's frames
                raise typer.BadParameter("altitude levels are flown with the MAVLink camera", param_hint="--levels")
            if baseline_levels is not None and autopilot != "ours":
                raise typer.BadParameter("--baseline-levels flies our SITL (a real autopilot flies --levels alone)",
                                         param_hint="--baseline-levels")
            if field is not None and baseline_levels is not None:
                raise typer.BadParameter("--baseline-levels flies a rectangle (fly --field with --levels alone)",
                                         param_hint="--baseline-levels")
            with_levels(GridConfig(), levels, detection)  # a bad table is a usage error naming it
        command = "uavsearch " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["flight-table"] else \
            "python -m missions flight-table"
        det = None if detection is None else str(detection)
        if baseline_levels is not None:
            from missions.flight_levels import compare_levels

            try:
                cmp = compare_levels(_seeds(first_seed, seeds), out, size or (10, 10, 5), levels, baseline_levels,
                                     workers, speedup, det, policy, max_moves, command)
            except ValueError as e:
                raise typer.BadParameter(str(e), param_hint="--baseline-levels") from e
            a, b = cmp["summary"]["levels"], cmp["summary"]["baseline"]
            typer.echo(f"levels {levels}: flight/grid mean {a['ratio_mean']}, max {a['ratio_max']}, found "
                       f"{a['found_pct']:.1f} %, search {a['search_s_mean']} s; levels {baseline_levels}: "
                       f"search {b['search_s_mean']} s; {out / 'flight_levels.md'}")
            return
        doc = flight_vs_grid(_seeds(first_seed, seeds), out, workers, speedup, policy, max_moves, autopilot, camera,
                             size=size, levels=levels, detection=det, field=field,
                             **({} if size is None and levels == 1 and field is None else {"command": command}))
        s = doc["summary"]
        typer.echo(f"flight/grid: mean {s['ratio_mean']}, max {s['ratio_max']}, over 1.5: {s['over_1_5']}; "
                   f"mean NEES {s['nees_mean']}; {out / 'flight_vs_grid.md'}")

    def _fleet_table(agents: int, seeds: int, first_seed: int, speedup: float, out: Path, width: int | None,
                     height: int | None, targets: int | None, autopilot: str, camera: str, levels: int,
                     field: Path | None, policy: str | None) -> None:
        import sys

        from missions.fleet_table import fleet_flight_table
        from sim.gridworld import ConfigError, GridConfig

        for bad, what in ((camera != "mavlink", "--camera"),
                          (levels != 1, "--levels"), (field is not None, "--field"), (policy is not None, "--policy")):
            if bad:
                raise typer.BadParameter("a fleet flies our SITL vehicles or real ArduCopter / PX4 SITL ones with "
                                         "their MAVLink cameras, one height, the team planner, on a rectangle (for now)",
                                         param_hint=what)
        if autopilot != "ours":  # no binary: one line before anything flies
            from sim.bridges.processes import (
                ARDUPILOT_ENV,
                PX4_ENV,
                AutopilotStartError,
                find_binary,
            )

            try:
                find_binary(None, ARDUPILOT_ENV if autopilot == "ardupilot" else PX4_ENV, autopilot)
            except AutopilotStartError as e:
                raise typer.BadParameter(str(e), param_hint="--autopilot") from e
        try:
            grid = GridConfig(width=width or 20, height=height or 20, n_targets=targets or 10)
        except ConfigError as e:
            raise typer.BadParameter(str(e)) from e
        command = "uavsearch " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["flight-table"] else \
            "python -m missions flight-table --agents"
        doc = fleet_flight_table(agents, grid, _seeds(first_seed, seeds), out, speedup, command=command,
                                 echo=typer.echo, autopilot=autopilot)
        s = doc["summary"]
        typer.echo(f"fleet of {agents}: makespan flight/grid mean {s['flight_grid_mean']:.3f}, max "
                   f"{s['flight_grid_max']:.3f}; truly found {s['truly_found_pct']:.1f} %; separation refused "
                   f"{s['separation_refused']}; {out / 'fleet_flights.md'}")

    @app.command("flight-pool")
    def flight_pool(
        tables: list[Path] = typer.Argument(..., help="flight_vs_grid.json files of one revision (e.g. seeds 0-19, 20-39)."),
        out: Path = typer.Option(Path("results"), "--out"),
    ) -> None:
        """Pool flight tables into one summary over all their flights, with 95 % intervals."""
        from missions.flight_table import pool_tables

        try:
            doc = pool_tables(tables, out)
        except ValueError as e:
            raise typer.BadParameter(str(e), param_hint="TABLES") from e
        s = doc["summary"]
        ci = s["ratio_mean_ci95"] or [float("nan")] * 2
        typer.echo(f"{s['flights']} flights: flight/grid mean {s['ratio_mean']:.3f} (95 %: {ci[0]:.3f}-{ci[1]:.3f}), "
                   f"over 1.5: {s['over_1_5']}; mean NEES {s['nees_mean']:.2f}; {out / 'flight_pool.md'}")

    @app.command("gps-table")
    def gps_table(
        seeds: int = typer.Option(12, "--seeds", help="Flights per row."),
        first_seed: int = typer.Option(0, "--first-seed"),
        sigma: list[float] = typer.Option([0.5, 1.0, 2.0], "--sigma", help="GPS sigma per axis (m), repeatable."),
        visit_map: list[str] = typer.Option(["hard", "probabilistic"], "--map", help="hard and/or probabilistic."),
        workers: int = typer.Option(2, "--workers", min=1),
        speedup: float = typer.Option(10.0, "--speedup", min=0.5),
        policy: str | None = typer.Option(None, "--policy"),
        max_moves: int = typer.Option(150, "--max-moves", min=1),
        out: Path = typer.Option(Path("results"), "--out"),
    ) -> None:
        """Moves and targets found over real flights for each GPS sigma, hard vs probabilistic map."""
        from missions.flight_table import gps_noise_table

        bad = [s for s in sigma if not s > 0]
        if bad:
            raise typer.BadParameter(f"{bad[0]}: a GPS sigma must be > 0 m", param_hint="--sigma")
        wrong = [m for m in visit_map if m not in ("hard", "probabilistic")]
        if wrong:
            raise typer.BadParameter(f"{wrong[0]!r}: must be hard or probabilistic", param_hint="--map")
        gps_noise_table(sigma, visit_map, _seeds(first_seed, seeds), out, workers, speedup, policy, max_moves)
        typer.echo(f"{out / 'gps_noise.md'}")
