"""`uavsearch run`: fly the search with the policy service against any MAVLink vehicle."""

from __future__ import annotations

from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def run(
        connect: str = typer.Option("udpin:0.0.0.0:14540", "--connect", help="pymavlink address of the vehicle."),
        origin_lat: float = typer.Option(..., "--origin-lat", help="Latitude of cell (0, 0)'s centre."),
        origin_lon: float = typer.Option(..., "--origin-lon", help="Longitude of cell (0, 0)'s centre."),
        origin_alt: float = typer.Option(30.0, "--origin-alt", help="Ground altitude AMSL (m)."),
        width: int = typer.Option(10, "--width"),
        height: int = typer.Option(10, "--height"),
        targets: int = typer.Option(5, "--targets", help="How many targets to find (|R|)."),
        altitude: float = typer.Option(3.5, "--altitude"),
        checkpoint: Path | None = typer.Option(None, "--checkpoint", help="Default: the shipped policy."),
        seed: int = typer.Option(0, "--seed"),
        out: Path = typer.Option(Path("out/run"), "--out"),
        tlog: bool = typer.Option(True, "--tlog/--no-tlog", help="Log the link to OUT/companion.tlog."),
    ) -> None:
        """Connect, arm, take off, search the field cell by cell, land; write the search log."""
        from autopilot_bridge.link import VehicleLink
        from autopilot_bridge.service import PolicyService, SearchSpec, save_log
        from policy.nn import load_policy
        from sim.gridworld import ConfigError, GridConfig
        from sim.gridworld.geodesy import HomePosition

        try:
            grid = GridConfig(width=width, height=height, n_targets=targets)
            origin = HomePosition(origin_lat, origin_lon, origin_alt)
        except (ConfigError, ValueError) as e:
            raise typer.BadParameter(str(e)) from e
        out.mkdir(parents=True, exist_ok=True)
        link = VehicleLink(connect, tlog=out / "companion.tlog" if tlog else None)
        try:
            service = PolicyService(link, load_policy(checkpoint, cfg=grid), SearchSpec(origin, grid, altitude), seed)
            service.take_off()
            log = service.run()
            service.land()
            save_log(log, out / "search_log.json")
            typer.echo(f"{len(log.cells) - 1} moves, {len(log.believed_found)} targets believed found; log in {out}")
        finally:
            link.close()
