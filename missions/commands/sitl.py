"""`uavsearch sitl`: run simulated vehicles that MAVSDK, MAVProxy and QGroundControl fly."""

from __future__ import annotations

import time
from enum import StrEnum
from pathlib import Path

import typer


class Physics(StrEnum):
    pybullet = "pybullet"
    kinematic = "kinematic"


def register(app: typer.Typer) -> None:
    @app.command()
    def sitl(
        instance: int = typer.Option(0, "--instance", "-i", min=0, max=39, help="First instance (ports offset by N)."),
        count: int = typer.Option(1, "--count", min=1, max=8, help="Vehicles to run, instances N, N+1, ..."),
        speedup: float = typer.Option(1.0, "--speedup", min=0.0, help="Lock-step speed-up; 0 = as fast as possible."),
        physics: Physics = typer.Option(Physics.pybullet, "--physics"),
        seed: int = typer.Option(0, "--seed", help="Seed of the field's episode and of the sensors."),
        lat: float = typer.Option(51.4545, "--lat", help="Field origin latitude."),
        lon: float = typer.Option(-2.5879, "--lon", help="Field origin longitude."),
        signing_key: str | None = typer.Option(None, "--signing-key", help="64 hex chars: require MAVLink2 signing."),
        tlog: Path | None = typer.Option(None, "--tlog", help="Write a .tlog (one per instance: NAME-N.tlog)."),
        duration: float | None = typer.Option(None, "--duration", help="Stop after this many simulated seconds."),
    ) -> None:
        """Start SITL vehicles (PX4 flavour) and print how to connect to them."""
        from sim.mavlink import Sitl, SitlConfig
        from sim.vehicle.geo import HomePosition

        key = None
        if signing_key is not None:
            try:
                key = bytes.fromhex(signing_key)
            except ValueError as e:
                raise typer.BadParameter("must be 64 hex characters", param_hint="--signing-key") from e
            if len(key) != 32:
                raise typer.BadParameter("must be 64 hex characters (32 bytes)", param_hint="--signing-key")
        vehicles = []
        for n in range(instance, instance + count):
            path = None if tlog is None else tlog.with_name(f"{tlog.stem}-{n}{tlog.suffix or '.tlog'}")
            cfg = SitlConfig(instance=n, speedup=speedup, physics=physics.value, home=HomePosition(lat, lon),
                             episode_seed=seed + n, seed=seed + n, signing_key=key, tlog=path)
            vehicles.append(Sitl(cfg))
            api, gcs = cfg.api_ports[1], cfg.gcs_ports[1]
            typer.echo(f"vehicle {n}: MAVSDK / companion  udpin://0.0.0.0:{api}")
            typer.echo(f"           MAVProxy            mavproxy.py --master=udpin:0.0.0.0:{gcs}")
            qgc = "connects by itself (UDP 14550)" if gcs == 14550 else f"add a UDP comm link on port {gcs}"
            typer.echo(f"           QGroundControl      {qgc}")
        for v in vehicles:
            v.start()
        try:
            while all(v._thread is not None and v._thread.is_alive() for v in vehicles):
                time.sleep(0.2)
                if duration is not None and all(v.t >= duration for v in vehicles):
                    break
        except KeyboardInterrupt:
            pass
        finally:
            for v in vehicles:
                v.stop()
