"""`uavsearch sitl`: run simulated vehicles that MAVSDK, MAVProxy and QGroundControl fly."""

from __future__ import annotations

import math
import signal
import time
from enum import StrEnum
from pathlib import Path

import numpy as np
import typer

from missions.commands import options as _levels  # --levels, --detection (docs/altitude.md)
from missions.commands.options import DIST, HEIGHT, MOTION, TARGETS, WIDTH, Dist, Motion


class Physics(StrEnum):
    pybullet = "pybullet"
    kinematic = "kinematic"


class Dialect(StrEnum):
    px4 = "px4"
    ardupilot = "ardupilot"
class Autopilot(StrEnum):
    ours = "ours"  # our SITL vehicle (sim.mavlink): its own controller, PX4's ports and dialect
    ardupilot = "ardupilot"  # ArduCopter SITL on our world's physics (JSON backend)
    px4 = "px4"  # PX4 SITL on our world's physics (simulator_mavlink, HIL)


def register(app: typer.Typer) -> None:
    @app.command()
    def sitl(
        instance: int = typer.Option(0, "--instance", "-i", min=0, max=39, help="First instance (ports offset by N)."),
        count: int = typer.Option(
            1, "--count", min=1, max=40,
            help="Vehicles to run, instances N, N+1, ... (N + count <= 40, PX4's port plan). Two or more share "
                 "one process, one physics step and one vectorised controller."),
        one_field: bool = typer.Option(
            False, "--one-field/--own-fields",
            help="With --count N: every vehicle on one field (the same targets), each on its own start cell, for "
                 "`uavsearch run --fleet` (docs/fleet_flight.md); default: each vehicle its own field (seed + N)."),
        speedup: float = typer.Option(1.0, "--speedup", min=0.0, help="Lock-step speed-up; 0 = as fast as possible."),
        physics: Physics = typer.Option(Physics.pybullet, "--physics"),
        dialect: Dialect = typer.Option(
            Dialect.px4, "--dialect",
            help="The autopilot the vehicle speaks as: px4 (PX4 SITL) or ardupilot (ArduCopter SITL: its modes, "
                 "GUIDED, failsafe parameters, telemetry only on request). Same UDP ports either way."),
        ekf_delay_s: float = typer.Option(
            3.0, "--ekf-delay-s", min=0.0,
            help="ardupilot: simulated seconds until the EKF has a position and GUIDED may arm (the real one ~40)."),
        seed: int = typer.Option(0, "--seed", help="Seed of the field's episode and of the sensors."),
        lat: float = typer.Option(51.4545, "--lat", help="Field origin latitude."),
        lon: float = typer.Option(-2.5879, "--lon", help="Field origin longitude."),
        alt: float = typer.Option(30.0, "--alt", help="Field origin altitude (m AMSL)."),
        width: int = WIDTH,
        height: int = HEIGHT,
        targets: int = TARGETS,
        distribution: Dist = DIST,
        motion: Motion = MOTION,
        cell_m: float = typer.Option(2.0, "--cell-m", help="Cell size (m); the simulated camera is built for 2 m."),
        target_step_s: float = typer.Option(
            4.0, "--target-step-s", help="Simulated seconds per grid-world step of moving targets (the companion's "
            "decision period: the herd moves at the grid world's pace per decision)."),
        field_edge: bool = typer.Option(
            True, "--field-edge/--no-field-edge",
            help="Render the paddock's edge (a track round the grass), which the companion registers its "
                 "position on near the borders; --no-field-edge: grass to the horizon."),
        field_out: Path = typer.Option(
            Path("out/sitl/field.json"), "--field-out",
            help="Write the field (origin, size, cell size, |R|, motion, address) here for `run --field`; "
                 "with --count > 1, NAME-N.json per vehicle."),
        fence_radius: float | None = typer.Option(
            None, "--fence-radius", min=1.0, help="Geofence: max metres from home (default: 100, or more for a large field)."),
        fence_alt: float = typer.Option(30.0, "--fence-alt", min=1.0, help="Geofence: max metres above home."),
        gcs_port_per_instance: bool = typer.Option(
            False, "--gcs-port-per-instance",
            help="Send GCS telemetry to 14550+N instead of PX4's shared 14550 (one MAVProxy per vehicle)."),
        signing_key_file: Path | None = typer.Option(
            None, "--signing-key-file", help="Require MAVLink2 signing: a chmod-600 file with 64 hex chars or a passphrase."),
        tlog: Path | None = typer.Option(None, "--tlog", help="Write a .tlog (one per instance: NAME-N.tlog)."),
        bind: str = typer.Option("0.0.0.0", "--bind", help="Local address the vehicle's ports listen on "
                                 "(127.0.0.1: this machine only)."),
        duration: float | None = typer.Option(None, "--duration", help="Stop after this many simulated seconds."),
        video_port: str = typer.Option(
            "0", "--video-port",
            help="Stream the camera as RTP/H.264 to this UDP port (5600: QGroundControl's 'UDP h.264 Video "
                 "Stream'; 0 or none: off); instance N streams to PORT+2N (a receiver takes PORT+1 for RTCP). "
                 "An SDP file goes next to the field file."),
        video_host: str = typer.Option("127.0.0.1", "--video-host", help="Where the video stream is sent (IPv4)."),
        video_rate: float = typer.Option(10.0, "--video-rate", help="Video frames per simulated second."),
        video_qp: int = typer.Option(
            0, "--video-qp", help="H.264 quantiser: 0 lossless (High 4:4:4 Predictive; FFmpeg and software "
            "decoders), 4 High profile for hardware decoders (colours within 5 levels)."),
        autopilot: Autopilot = typer.Option(
            Autopilot.ours, "--autopilot",
            help="Who flies: ours (our SITL vehicle), or a real ardupilot / px4 SITL binary taking its physics from "
                 "our world (the PyBullet body driven by its motor commands, the same field and targets)."),
        autopilot_bin: Path | None = typer.Option(
            None, "--autopilot-bin", help="The autopilot binary (arducopter / px4); default $ARDUPILOT_SITL / $PX4_SITL."),
        polygon_field: Path | None = typer.Option(
            None, "--field",
            help="A real field (field.json from `uavsearch field`): the world renders its polygon (grass inside, "
                 "the track along its edge, water or roofs in its no-fly zones), home and targets on its searchable "
                 "cells; its origin and grid replace --lat/--lon/--alt/--width/--height. Our vehicle only."),
        camera_px: int = typer.Option(
            50, "--camera-px",
            help="The downward camera's resolution, pixels a side (16..1024; 100 deg FoV at any size). The "
                 "companion reads the size from each frame; `uavsearch detector-curve --camera-px` measures what "
                 "its detector sees at that size from each flying height."),
        levels: int = _levels.LEVELS,
        detection: Path | None = _levels.DETECTION,
    ) -> None:
        """Start SITL vehicles (PX4 or ArduCopter flavour) and print how to connect to them."""
        from missions.fieldfile import FieldSpec, write_field
        from missions.ports import udp_port_taken
        from provenance import atomic_write_bytes
        from sim.gridworld import ConfigError, GridConfig
        from sim.mavlink import Geofence, Sitl, SitlConfig, SitlFleet
        from sim.mavlink.video import VideoConfig, sdp_text
        from sim.vehicle.geo import HomePosition

        if instance + count > 40:
            raise typer.BadParameter(f"instances {instance}..{instance + count - 1} pass 39: PX4's ports 14540+N "
                                     "would meet 14580+M", param_hint="--count")
        # keys come from a file with safe permissions only: argv is readable by every user in /proc
        key: bytes | None = None
        if signing_key_file is not None:
            from missions.keys import KeyFileError, read_signing_key

            try:
                key = read_signing_key(signing_key_file)
            except KeyFileError as e:
                raise typer.BadParameter(str(e), param_hint="--signing-key-file") from e
        if not (math.isfinite(target_step_s) and target_step_s > 0):
            raise typer.BadParameter(f"{target_step_s}: must be > 0 s", param_hint="--target-step-s")
        from sim.vehicle.scene import check_camera_px

        try:
            check_camera_px(camera_px)
        except ValueError as e:
            raise typer.BadParameter(str(e), param_hint="--camera-px") from e
        if cell_m != 2.0:
            raise typer.BadParameter(f"only 2 m cells are simulated so far (got {cell_m}): the camera, the field "
                                     "and the detector are built for 2 m", param_hint="--cell-m")
        pf = None
        if polygon_field is not None:
            pf = _polygon(polygon_field, autopilot != Autopilot.ours, count, one_field)
            width, height = pf.width, pf.height
            lat, lon, alt = pf.origin.lat_deg, pf.origin.lon_deg, pf.origin.alt_m
        try:
            grid = GridConfig(width=width, height=height, n_targets=targets, distribution=distribution.value,
                              motion=motion.value)
            origin = HomePosition(lat, lon, alt)
        except (ConfigError, ValueError) as e:
            raise typer.BadParameter(str(e)) from e
        # altitude levels: the field file tells `run --field` to fly them; the vehicle's world is
        # the same (the camera renders at any height), its frame checked to cover the top window
        if one_field and count > 1 and levels > 1:
            raise typer.BadParameter("a fleet on one field flies one height's cells for now (docs/fleet_flight.md)",
                                     param_hint="--levels")
        search_grid = _with_levels(grid, levels, detection)
        # the fence must hold the whole field seen from any spawn cell: its diagonal, and a margin
        diagonal = float(np.hypot(width, height)) * cell_m
        if fence_radius is None:
            fence_radius = max(100.0, 1.2 * diagonal + 10.0)
        elif fence_radius < diagonal:
            typer.echo(f"warning: --fence-radius {fence_radius:g} m is smaller than the field's diagonal "
                       f"({diagonal:.0f} m): some cells may be out of reach", err=True)
        if autopilot != Autopilot.ours:
            _real_autopilot(autopilot.value, autopilot_bin, instance, count, speedup, physics, origin, grid, seed,
                            target_step_s, field_edge, field_out, fence_radius, fence_alt, gcs_port_per_instance,
                            key, tlog, duration, cell_m, camera_px, one_field=one_field, search_grid=search_grid)
            return
        vport = 0 if video_port.strip().lower() in ("0", "none", "off", "") else None
        if vport is None:
            try:
                vport = int(video_port)
            except ValueError:
                raise typer.BadParameter(f"{video_port!r}: a UDP port, or 0 / none for no video",
                                         param_hint="--video-port") from None
        if vport and not 1 <= vport <= 65534 - 2 * count:
            raise typer.BadParameter(f"{vport}: must be a UDP port 1..{65534 - 2 * count}", param_hint="--video-port")
        cfgs = []
        starts = None
        if one_field and count > 1:
            starts = _team_starts(grid, seed, count, None if pf is None else pf.mask)
        for n in range(instance, instance + count):
            try:
                probe = SitlConfig(instance=n, gcs_remote_port=14550 + n if gcs_port_per_instance else None, bind=bind)
            except ValueError as e:
                raise typer.BadParameter(str(e), param_hint="--bind") from e
            for port, what in ((probe.api_ports[0], "API link"), (probe.gcs_ports[0], "GCS link")):
                if udp_port_taken(port):
                    raise typer.BadParameter(
                        f"UDP port {port} ({what} of instance {n}) is taken: is another `uavsearch sitl "
                        f"--instance {n}` running? Stop it or pick another --instance.", param_hint="--instance")
            path = None if tlog is None else tlog.with_name(f"{tlog.stem}-{n}{tlog.suffix or '.tlog'}")
            try:
                video = VideoConfig(port=vport + 2 * (n - instance) if vport else 0, host=video_host, rate_hz=video_rate,
                                    qp=video_qp)
            except ValueError as e:
                raise typer.BadParameter(str(e), param_hint="--video-port/--video-host/--video-rate/--video-qp") from e
            cfg = SitlConfig(instance=n, speedup=speedup, physics=physics.value, home=origin, grid=grid, camera=True,
                             camera_px=camera_px,
                             target_step_s=target_step_s, field_edge=field_edge,
                             episode_seed=seed + n if starts is None else seed, seed=seed + n, signing_key=key,
                             tlog=path, spawn_cell=None if starts is None else starts[n - instance],
                             geofence=Geofence(fence_radius, fence_alt),
                             gcs_remote_port=14550 + n if gcs_port_per_instance else None, bind=bind,
                             dialect=dialect.value, ekf_delay_s=ekf_delay_s, video=video,
                             **({} if pf is None else {"polygon": pf}))
            cfgs.append(cfg)
            api, gcs = cfg.api_ports[1], cfg.gcs_ports[1]
            typer.echo(f"vehicle {n} (MAVLink system {cfg.sysid}, {dialect.value}):")
            typer.echo(f"    MAVSDK / companion  udpin://0.0.0.0:{api}")
            typer.echo(f"    MAVProxy            mavproxy.py --master=udpin:0.0.0.0:{gcs}")
            qgc = "connects by itself (UDP 14550)" if gcs == 14550 else f"add a UDP comm link on port {gcs}"
            typer.echo(f"    QGroundControl      {qgc}")
            typer.echo(f"    camera              MAVLink camera component {cfg.sysid}/100 on the same links "
                       "(uavsearch run --camera mavlink)")
            fpath = field_out if count == 1 else field_out.with_name(f"{field_out.stem}-{n}{field_out.suffix or '.json'}")
            uri = sdp_name = None
            if video.enabled:
                sdp_path = fpath.with_suffix(".sdp")
                atomic_write_bytes(sdp_path, sdp_text(video).encode("ascii"))
                uri, sdp_name = f"udp://:{video.port}", sdp_path.name
                typer.echo(f"    video               RTP/H.264 to {video.host}:{video.port} ({video.rate_hz:g} Hz "
                           f"simulated), SDP {sdp_path}; QGroundControl: Video Source 'UDP h.264 Video Stream', "
                           f"port {video.port}")
            write_field(fpath, FieldSpec(origin, search_grid, cell_m, f"udpin:0.0.0.0:{api}", n, physics.value, field_edge,
                                         dialect=dialect.value, autopilot="ours", video_uri=uri, video_sdp=sdp_name,
                                         polygon=None if pf is None else str(polygon_field.resolve()),
                                         team=None if starts is None else count),
                        seed + n, sitl=cfg.to_dict())
            typer.echo(f"    field               {width} x {height} cells of {cell_m:g} m, {targets} targets "
                       f"({distribution.value}, {motion.value}); cell (0, 0) at {lat:.7f}, {lon:.7f}, {alt:g} m")
            if levels > 1:
                typer.echo(f"    levels              {levels} (heights {_heights(levels)} m over home; the camera's "
                           f"frame reaches {_margin(levels):.1f} m beyond level {levels}'s {2 * levels + 1} x "
                           f"{2 * levels + 1} cells)")
            if pf is not None:
                typer.echo(f"    real field          {polygon_field}: heading {pf.heading_deg:.2f} deg, "
                           f"{pf.searchable_cells} searchable cells (targets and home on them)")
            typer.echo(f"    companion           uavsearch run --field {fpath}" + (" [--camera video]" if uri else ""))
        if key is not None:
            typer.echo("MAVLink2 signing is on: unsigned commands are dropped (MAVProxy: `signing key` with "
                       "the file's passphrase, or the same 32-byte key).")

        def terminate(_signum: int, _frame: object) -> None:  # SIGTERM stops as cleanly as Ctrl-C
            raise KeyboardInterrupt

        signal.signal(signal.SIGTERM, terminate)
        runner = Sitl(cfgs[0]) if count == 1 else SitlFleet(cfgs)
        runner.start()
        try:
            while runner.running:
                time.sleep(0.2)
                if duration is not None and runner.t >= duration:
                    break
        except KeyboardInterrupt:
            pass
        finally:
            runner.stop()


def _with_levels(grid, levels: int, detection: Path | None):
    """The search grid with altitude levels (the field file's), refused where the camera's frame
    would not cover the top level's window at its height (autopilot_bridge.service.height)."""
    from autopilot_bridge.service.height import footprint_margin_m
    from missions.commands.options import with_levels

    if levels == 1 and detection is None:
        return grid
    if footprint_margin_m(levels) < 0:
        raise typer.BadParameter(f"the camera's frame does not cover level {levels}'s window", param_hint="--levels")
    return with_levels(grid, levels, detection)


def _heights(levels: int) -> str:
    from sim.gridworld import level_height_m

    return " / ".join(f"{level_height_m(lv):.2f}" for lv in range(1, levels + 1))


def _margin(levels: int) -> float:
    from autopilot_bridge.service.height import footprint_margin_m

    return footprint_margin_m(levels)


def _polygon(path: Path, real_autopilot: bool, count: int, one_field: bool = False):
    """The real field `sitl --field` renders, loaded and checked; a bad file is one usage error.
    Several vehicles share it only as one fleet's (--count N --one-field: `run --fleet`)."""
    from sim.field import FieldError, load_field
    from sim.gridworld.masks import largest_component

    if real_autopilot or (count != 1 and not one_field):
        raise typer.BadParameter("a real field is flown by our SITL vehicles, one at a time or as one fleet "
                                 "(--autopilot ours, --count 1, or --count N --one-field)", param_hint="--field")
    try:
        pf = load_field(str(path))
    except FieldError as e:
        raise typer.BadParameter(str(e), param_hint="--field") from e
    if pf.cell_m != 2.0:
        raise typer.BadParameter(f"{path}: its cells are {pf.cell_m:g} m; the simulated camera is built for 2 m "
                                 "(uavsearch field --cell-m 2)", param_hint="--field")
    if int(largest_component(np.asarray(pf.mask, bool)).sum()) < 2:
        raise typer.BadParameter(f"{path}: fewer than 2 searchable cells", param_hint="--field")
    return pf


def _team_starts(grid, seed: int, count: int, mask=None) -> list[tuple[int, int]]:
    """The start cells of `count` vehicles on one field: the team grid world's (the episode's
    start cell, then cells free of targets and of the others, sim.gridworld.team.team_starts),
    so the fleet flight starts where the team world of the same seed does. mask: a real field's
    (its largest 4-connected part, as the scene places the episode on it)."""
    from sim.gridworld import ConfigError, sample_episodes
    from sim.gridworld.masks import largest_component
    from sim.gridworld.team import team_starts

    m = None if mask is None else largest_component(np.asarray(mask, bool))
    try:
        s = team_starts(sample_episodes(grid, 1, seed, mask=m), count)[0]
    except ConfigError as e:
        raise typer.BadParameter(str(e), param_hint="--count") from e
    return [(int(x), int(y)) for x, y in s]


def _real_autopilot(autopilot: str, binary: Path | None, instance: int, count: int, speedup: float,
                    physics: Physics, origin, grid, seed: int, target_step_s: float, field_edge: bool,
                    field_out: Path, fence_radius: float, fence_alt: float, gcs_port_per_instance: bool,
                    key: bytes | None, tlog: Path | None, duration: float | None, cell_m: float,
                    camera_px: int = 50, one_field: bool = False, search_grid=None) -> None:
    """`sitl --autopilot ardupilot|px4`: our world (body, field, targets) as the real binary's
    physics, the field file pointing the companion at the binary's API link. With `--count N
    --one-field`: N binaries (instances I..I+N-1: their own physics, API, camera and GCS ports,
    system ids I+1...), each flying a world of its own on the one episode from the team grid
    world's start cell, all in this process; one field file each for `run --fleet`.
    search_grid: the grid the field file tells `run --field` to search (with the altitude
    levels; None: `grid`), the world simulating its single-height twin (`grid`), as for our
    vehicle."""
    from missions.fieldfile import FieldSpec, write_field
    from missions.ports import udp_port_taken
    from sim.bridges.ardupilot_json import json_port
    from sim.bridges.processes import ARDUPILOT_ENV, PX4_ENV, AutopilotStartError, find_binary
    from sim.bridges.px4_hil import simulator_port
    from sim.bridges.world import AutopilotWorld, AutopilotWorldConfig

    fleet = count > 1
    for bad, what, hint in ((fleet and not one_field, "one vehicle (--count 1), or a fleet on one field (--count N "
                             "--one-field)", "--count"),
                            (physics != Physics.pybullet, "the PyBullet body (--physics pybullet)", "--physics"),
                            (key is not None, "no MAVLink signing of ours (set the autopilot's own)", "--signing-key-file"),
                            (tlog is not None, "no .tlog of ours (the autopilot logs itself)", "--tlog"),
                            (speedup == 0 and autopilot == "ardupilot", "a --speedup > 0 (it paces itself)", "--speedup")):
        if bad:
            raise typer.BadParameter(f"--autopilot {autopilot} runs {what}", param_hint=hint)
    try:
        find_binary(binary, ARDUPILOT_ENV if autopilot == "ardupilot" else PX4_ENV, autopilot)
    except AutopilotStartError as e:
        raise typer.BadParameter(str(e), param_hint="--autopilot-bin") from e
    starts = _team_starts(grid, seed, count) if fleet else None
    worlds: list[AutopilotWorld] = []
    paths: list[Path] = []
    for k, n in enumerate(range(instance, instance + count)):
        if autopilot == "ardupilot":
            fence = {"FENCE_ENABLE": 1, "FENCE_TYPE": 3, "FENCE_RADIUS": fence_radius, "FENCE_ALT_MAX": fence_alt}
            taken = udp_port_taken(json_port(n)) or udp_port_taken(14540 + n)
            what = f"UDP {json_port(n)} (JSON physics) or {14540 + n} (API link)"
        else:
            fence = {"GF_MAX_HOR_DIST": fence_radius, "GF_MAX_VER_DIST": fence_alt}
            import socket

            with socket.socket() as s:
                taken = s.connect_ex(("127.0.0.1", simulator_port(n))) == 0
            what = f"TCP {simulator_port(n)} (PX4's simulator port)"
        if taken:
            raise typer.BadParameter(f"{what} of instance {n} is taken: is another sitl on instance {n} running?",
                                     param_hint="--instance")
        # a fleet's vehicles fly one episode (the seed's), each its own sensors (seed + n), as ours do
        cfg = AutopilotWorldConfig(autopilot=autopilot, instance=n, speedup=speedup, binary=binary, home=origin,
                                   grid=grid, episode_seed=seed if fleet else seed + n, seed=seed + n, camera=True,
                                   camera_px=camera_px, field_edge=field_edge, target_step_s=target_step_s,
                                   gcs_port=14550 + n if gcs_port_per_instance else 14550, params=fence,
                                   spawn_cell=None if starts is None else starts[k])
        world = AutopilotWorld(cfg)
        worlds.append(world)
        address = world.companion_address()
        connect = address.replace("udpin:127.0.0.1:", "udpin:0.0.0.0:")
        fpath = field_out if not fleet else field_out.with_name(f"{field_out.stem}-{n}{field_out.suffix or '.json'}")
        paths.append(fpath)
        write_field(fpath, FieldSpec(origin, search_grid or grid, cell_m, connect, n, "pybullet", field_edge, dialect=autopilot,
                                     autopilot=autopilot, camera=world.camera_address(),
                                     launch_ne=tuple(float(v) for v in world.scene.spawn_ne),
                                     team=count if fleet else None),
                    seed + n, sitl=cfg.to_dict())
        typer.echo(f"{autopilot} instance {n} (MAVLink system {cfg.sysid}) on our world's physics:")
        typer.echo(f"    companion           uavsearch run --field {fpath}   ({connect})")
        if world.camera_address() is not None:
            typer.echo(f"    camera              MAVLink camera component {cfg.sysid}/100 on UDP {cfg.camera_ports[0]} -> "
                       f"{cfg.camera_ports[1]} (run --camera {world.camera_address()})")
        typer.echo(f"    field               {grid.width} x {grid.height} cells of {cell_m:g} m, {grid.n_targets} targets; "
                   f"cell (0, 0) at {origin.lat_deg:.7f}, {origin.lon_deg:.7f}, {origin.alt_m:g} m"
                   + ("" if starts is None else f"; starts on cell {tuple(starts[k])}"))
        if search_grid is not None and search_grid.levels > 1:
            typer.echo(f"    levels              {search_grid.levels} (heights {_heights(search_grid.levels)} m over home, "
                       f"flown on {autopilot}'s own height estimate)")
    if fleet:
        typer.echo(f"fleet              uavsearch run --fleet {' '.join(str(p) for p in paths)}")

    def terminate(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, terminate)
    started: list[AutopilotWorld] = []  # a world that fails to start has stopped itself
    try:
        try:
            for world in worlds:
                world.start()
                started.append(world)
        except AutopilotStartError as e:
            raise typer.BadParameter(str(e), param_hint="--autopilot-bin") from e
        while all(w.process is not None and w.process.alive for w in worlds):
            time.sleep(0.2)
            if duration is not None and min(w.t for w in worlds) >= duration:
                break
        for w in worlds:
            if w.process is not None and not w.process.alive:
                typer.echo(f"error: {autopilot} instance {w.cfg.instance} exited:\n{w.process.tail()}", err=True)
    except KeyboardInterrupt:
        pass
    finally:
        for w in started:
            w.stop()
