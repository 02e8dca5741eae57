"""`uavsearch run`: fly the search with the policy service against any MAVLink vehicle.

Every exit path brings the vehicle down (see missions/guarded.py) and writes the search log;
the exit status says how it ended: 0 all |R| found and landed, 3 the search ended short of |R|,
1 a failure (the vehicle was sent to --on-abort), 128+N interrupted by signal N (130 Ctrl-C).

After every decision the search's state goes into OUT/journal.json (autopilot_bridge.service.journal):
`uavsearch run --resume OUT` after a crash of this process goes on with the same search, the
vehicle taken back in the air or taken off again (autopilot_bridge.service.resume), and its log is the
whole search."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import typer

from autopilot_bridge.service.abort import AbortAction
from missions.commands import options as _levels  # --levels, --detection (docs/altitude.md)
from missions.commands.options import Dist, Motion

#: wall seconds the camera component has to heartbeat and describe itself (the vehicle may be
#: starting: `take_off` waits 10 s for its heartbeat too)
CAMERA_TIMEOUT_S = 10.0


def _check(ok: bool, value: object, hint: str, why: str) -> None:
    if not ok:
        raise typer.BadParameter(f"{value!r}: {why}", param_hint=hint)


def register(app: typer.Typer) -> None:
    @app.command()
    def run(
        field: Path | None = typer.Option(
            None, "--field", help="The field file `uavsearch sitl` wrote (origin, size, |R|, motion, address), or a "
                                  "real field's field.json (`uavsearch field`): its grid at its heading, its "
                                  "searchable cells only, its fence uploaded."),
        connect: str | None = typer.Option(
            None, "--connect", help="pymavlink address of the vehicle (default: the field file's, else udpin:0.0.0.0:14540)."),
        origin_lat: float | None = typer.Option(None, "--origin-lat", help="Latitude of cell (0, 0)'s centre."),
        origin_lon: float | None = typer.Option(None, "--origin-lon", help="Longitude of cell (0, 0)'s centre."),
        origin_alt: float | None = typer.Option(None, "--origin-alt", help="Ground altitude AMSL (m) (default: 30)."),
        width: int | None = typer.Option(None, "--width", help="Grid width (cells) (default: field file, else 10)."),
        height: int | None = typer.Option(None, "--height", help="Grid height (cells) (default: field file, else 10)."),
        targets: int | None = typer.Option(None, "--targets", help="How many targets to find, |R| (default: 5)."),
        distribution: Dist | None = typer.Option(None, "--distribution", help="Target placement (default: random)."),
        motion: Motion | None = typer.Option(None, "--motion", help="Target motion (default: static)."),
        cell_m: float | None = typer.Option(None, "--cell-m", help="Cell size (m) (default: field file, else 2)."),
        policy: str | None = typer.Option(None, "--policy", help="A registered policy (see `uavsearch eval --help`)."),
        checkpoint: Path | None = typer.Option(None, "--checkpoint", help="A trained network or DRQN checkpoint."),
        field_edge: bool | None = typer.Option(
            None, "--field-edge/--no-field-edge",
            help="The field's edge is visible (a track round the grass): a border not in view is evidence of "
                 "where the vehicle is (default: the field file's, else no)."),
        altitude: float | None = typer.Option(None, "--altitude", help="Search altitude above home (m), 1 to 30 "
                                              "(default: 3.5)."),
        max_moves: int | None = typer.Option(None, "--max-moves", help="Stop after this many moves (default: t_e)."),
        move_timeout: float = typer.Option(20.0, "--move-timeout", help="Seconds one move may take before aborting."),
        on_abort: AbortAction = typer.Option(
            AbortAction.rtl, "--on-abort", help="What the vehicle does when the search fails or is interrupted."),
        abort_timeout: float = typer.Option(120.0, "--abort-timeout", help="Seconds to wait for the disarm after an abort."),
        hold_time: float = typer.Option(60.0, "--hold-time", help="With --on-abort hold: seconds left to the operator before landing."),
        seed: int | None = typer.Option(None, "--seed", help="The search's seed (default: 0)."),
        out: Path = typer.Option(Path("out/run"), "--out"),
        resume: Path | None = typer.Option(
            None, "--resume", help="Go on with the search whose journal is in this directory (a run's --out) after "
                                   "the companion stopped: same field, policy and seed; the vehicle is taken back "
                                   "in the air, or taken off again if it has landed."),
        tlog: bool = typer.Option(True, "--tlog/--no-tlog", help="Log the link to OUT/companion.tlog."),
        autopilot: str = typer.Option(
            "auto", "--autopilot", help="The autopilot's family: px4, ardupilot, or auto (from its HEARTBEAT)."),
        set_failsafe: bool = typer.Option(
            False, "--set-failsafe", help="Set the vehicle's companion-loss failsafe to safe values where it would "
                                          "leave the vehicle flying without this companion (default: refuse to fly)."),
        signing_key_file: Path | None = typer.Option(
            None, "--signing-key-file", help="Sign the link (MAVLink 2): a chmod-600 file with 64 hex chars or a passphrase."),
        camera: str | None = typer.Option(
            None, "--camera",
            help="Where frames come from: mavlink (the MAVLink camera component on the vehicle's link), "
                 "mavlink:ADDRESS (the camera component on its own pymavlink address, e.g. udpin:0.0.0.0:14560), "
                 "video (the field file's video stream), or a video URL PyAV opens: udp://:5600 (RTP, with its SDP), "
                 "rtsp://..., /dev/videoN, a file (default: the field file's camera, else mavlink)."),
        video_sdp: Path | None = typer.Option(
            None, "--video-sdp", help="The SDP file of an RTP video stream (default: the field file's)."),
        levels: int | None = typer.Option(
            None, "--levels", min=1, max=3, help="Altitude levels to fly: climb and descend are moves, level l at "
            "3.5 m (2 l + 1) / 3 over home (docs/altitude.md) (default: the field file's, else 1)."),
        detection: Path | None = _levels.DETECTION,
        fleet: bool = typer.Option(
            False, "--fleet", help="Fly several vehicles on one field with one companion, one shared belief and the "
            "team planner: give the field files `uavsearch sitl --count N --one-field` wrote (docs/fleet_flight.md)."),
        fleet_fields: list[Path] | None = typer.Argument(None, help="With --fleet: one field file per vehicle."),
    ) -> None:
        """Connect, arm, take off, search the field cell by cell, land; write the search log."""
        if fleet or fleet_fields:
            _check(fleet and bool(fleet_fields), fleet_fields, "--fleet", "give --fleet and the vehicles' field files")
            from missions.fleet_flight import run_fleet

            raise typer.Exit(run_fleet(fleet_fields, out, 0 if seed is None else seed,
                                       on_abort="land" if on_abort == AbortAction.rtl else on_abort.value,
                                       altitude=3.5 if altitude is None else altitude, max_moves=max_moves,
                                       move_timeout_s=move_timeout, abort_timeout_s=abort_timeout, tlog=tlog,
                                       echo=typer.echo, set_failsafe=set_failsafe))
        from autopilot_bridge.link.connection import VehicleLink
        from autopilot_bridge.link.dialects import NAMES as AUTOPILOTS
        from autopilot_bridge.service.journal import (
            ENDED,
            JOURNAL,
            Journal,
            JournalError,
            load,
            read,
        )
        from autopilot_bridge.service.policy_service import PolicyService, SearchSpec, save_log
        from autopilot_bridge.service.resume import rejoin
        from missions.field_run import field_spec
        from missions.fieldfile import FieldFileError, FieldSpec, read_field
        from missions.flight_policy import PolicyUnfit, flight_policy
        from missions.guarded import EXIT_OK, EXIT_SHORT, guarded_search
        from missions.ports import udp_port_taken, udpin_port
        from missions.progress import FlightProgress
        from provenance import stamp
        from sim.gridworld import ConfigError, GridConfig
        from sim.gridworld.geodesy import HomePosition

        _check(autopilot.lower() in AUTOPILOTS, autopilot, "--autopilot", f"expected one of {', '.join(AUTOPILOTS)}")
        doc = None
        if resume is not None:
            try:
                doc = read(resume)
            except JournalError as e:
                raise typer.BadParameter(str(e), param_hint="--resume") from e
            if doc.status == ENDED:
                raise typer.BadParameter(f"the search journaled in {doc.path} ran to its end ({doc.meta['moves']} "
                                         "moves): nothing to resume", param_hint="--resume")
            jc = doc.config
            for given, key, hint in ((width, "width", "--width"), (height, "height", "--height"),
                                     (targets, "n_targets", "--targets"),
                                     (None if distribution is None else distribution.value, "distribution", "--distribution"),
                                     (None if motion is None else motion.value, "motion", "--motion")):
                _check(given is None or given == jc["grid"][key], given, hint,
                       f"the journaled search ({doc.path}) flies {key} {jc['grid'][key]!r}")
            for given, key, hint in ((policy, "policy", "--policy"), (altitude, "altitude", "--altitude"),
                                     (max_moves, "max_moves", "--max-moves"), (field_edge, "field_edge", "--field-edge"),
                                     (None if checkpoint is None else str(checkpoint), "checkpoint", "--checkpoint")):
                _check(given is None or given == jc[key], given, hint,
                       f"the journaled search ({doc.path}) has {key} {jc[key]!r}")
            _check(seed is None or seed == doc.seed, seed, "--seed", f"the journaled search ({doc.path}) has seed {doc.seed}")
            _check(out == Path("out/run") or out.resolve() == resume.resolve(), str(out), "--out",
                   "a resumed search writes into its --resume directory")
            out = resume
            policy, altitude, max_moves, field_edge, seed = jc["policy"], jc["altitude"], jc["max_moves"], jc["field_edge"], doc.seed
            checkpoint = None if jc["checkpoint"] is None else Path(jc["checkpoint"])
            width, height, targets = jc["grid"]["width"], jc["grid"]["height"], jc["grid"]["n_targets"]
            distribution, motion = Dist(jc["grid"]["distribution"]), Motion(jc["grid"]["motion"])
            o = jc["origin"]
            for given, value, hint in ((origin_lat, o[0], "--origin-lat"), (origin_lon, o[1], "--origin-lon"),
                                       (origin_alt, o[2], "--origin-alt")):
                _check(given is None or given == value, given, hint, f"the journaled search ({doc.path}) has {value!r}")
            origin_lat, origin_lon, origin_alt = o
            connect = connect or jc["connect"]
            # the journaled search's field file (its camera, launch pad, dialect) and camera
            if field is None and jc.get("field") and Path(jc["field"]).is_file():
                field = Path(jc["field"])
            camera = camera or jc.get("camera")
        elif (out / JOURNAL).exists():
            try:
                old = read(out)
            except JournalError:
                old = None
            if old is not None and old.status != ENDED:
                raise typer.BadParameter(
                    f"{old.path} is the journal of a search that has not ended ({old.meta['moves']} moves flown): go "
                    f"on with it (uavsearch run --resume {out}), or give another --out", param_hint="--out")
        altitude = 3.5 if altitude is None else altitude
        seed = 0 if seed is None else seed

        fs: FieldSpec | None = None
        pf = None  # a real field (sim.field.PolygonField): given itself, or named by the SITL's field file
        if field is not None:
            from missions.field_run import is_polygon_file, load_polygon

            try:
                if is_polygon_file(field):
                    pf = load_polygon(field)
                else:
                    fs = read_field(field)
                    pf = None if fs.polygon is None else load_polygon(Path(fs.polygon))
            except (FieldFileError, ValueError) as e:
                raise typer.BadParameter(str(e), param_hint="--field") from e
        if fs is not None and doc is not None:
            jg, jo = doc.config["grid"], doc.config["origin"]
            here = (fs.grid.width, fs.grid.height, fs.grid.n_targets, fs.origin.lat_deg, fs.origin.lon_deg)
            there = (jg["width"], jg["height"], jg["n_targets"], jo[0], jo[1])
            _check(here == there, str(field), "--field",
                   f"this field ({here[0]} x {here[1]}, {here[2]} targets, origin {here[3]}, {here[4]}) is not the "
                   f"journaled search's ({doc.path}: {there[0]} x {there[1]}, {there[2]} targets, origin "
                   f"{there[3]}, {there[4]})")
        if fs is None and pf is None and (origin_lat is None or origin_lon is None):
            raise typer.BadParameter("give --field FILE (written by `uavsearch sitl`) or both --origin-lat and "
                                     "--origin-lon (the centre of cell (0, 0))", param_hint="--field")
        g0 = fs.grid if fs is not None else GridConfig()
        o0 = fs.origin if fs is not None else HomePosition(0.0, 0.0, 30.0)
        if pf is not None:  # the real field's grid and origin: not to be changed by hand
            from missions.field_run import on_polygon_grid

            g0, o0 = on_polygon_grid(pf, g0), pf.origin
            for given, hint in ((width, "--width"), (height, "--height"), (origin_lat, "--origin-lat"),
                                (origin_lon, "--origin-lon"), (cell_m, "--cell-m")):
                _check(given is None, given, hint, f"the real field {pf.source!r} sets it")

        def pick(given, from_field):  # an explicit option wins over the field file
            return from_field if given is None else given

        for v, hint in ((altitude, "--altitude"), (move_timeout, "--move-timeout"), (abort_timeout, "--abort-timeout"),
                        (hold_time, "--hold-time")):
            _check(math.isfinite(v), v, hint, "must be a finite number")
        _check(1.0 <= altitude <= 30.0, altitude, "--altitude", "the search altitude must be 1 to 30 m above home "
               "(the camera's 3 x 3-cell view is built for 3.5 m)")
        _check(move_timeout > 0, move_timeout, "--move-timeout", "must be > 0 s")
        _check(abort_timeout > 0, abort_timeout, "--abort-timeout", "must be > 0 s")
        _check(hold_time >= 0, hold_time, "--hold-time", "must be >= 0 s")
        _check(max_moves is None or max_moves >= 1, max_moves, "--max-moves", "must be >= 1")
        cell = pick(cell_m, fs.cell_m if fs is not None else 2.0)
        _check(cell == 2.0, cell, "--cell-m", "only 2 m cells are flown so far (the detector and the camera "
               "altitude are built for 2 m)")
        try:
            motion_v = motion.value if motion is not None else g0.motion
            grid = GridConfig(
                width=pick(width, g0.width), height=pick(height, g0.height), n_targets=pick(targets, g0.n_targets),
                distribution=distribution.value if distribution is not None else g0.distribution,
                motion=motion_v, map_variant="spatial" if motion_v == "static" else "spatiotemporal")
            origin = HomePosition(pick(origin_lat, o0.lat_deg), pick(origin_lon, o0.lon_deg), pick(origin_alt, o0.alt_m))
        except (ConfigError, ValueError) as e:
            raise typer.BadParameter(str(e)) from e
        if doc is None and (levels is not None or detection is not None or g0.levels > 1):
            # altitude levels: the option's, else the field file's (with its detection table)
            if detection is None and levels in (None, g0.levels):
                import dataclasses

                grid = dataclasses.replace(grid, levels=g0.levels, detection=g0.detection)
            else:
                grid = _levels.with_levels(grid, g0.levels if levels is None else levels, detection)
        if doc is not None:  # the journaled search's field exactly (its target period too)
            grid = GridConfig.from_dict(doc.config["grid"])
        if fs is not None and (grid.width, grid.height, grid.n_targets) != (g0.width, g0.height, g0.n_targets):
            typer.echo(f"warning: flying a {grid.width} x {grid.height} field with {grid.n_targets} targets; "
                       f"{field} says {g0.width} x {g0.height} with {g0.n_targets}", err=True)
        edge = pick(field_edge, fs.edge if fs is not None else False)
        address = connect or (fs.connect if fs is not None and fs.connect else "udpin:0.0.0.0:14540")
        from autopilot_bridge.link.connection import check_address

        try:
            check_address(address)
        except ValueError as e:
            raise typer.BadParameter(str(e), param_hint="--connect") from e
        port = udpin_port(address)
        if port is not None and udp_port_taken(port):
            raise typer.BadParameter(f"UDP port {port} is taken: is another `uavsearch run` connected to this "
                                     "vehicle? Stop it first", param_hint="--connect")
        from autopilot_bridge.camera import (
            CameraNotFound,
            CameraSpecError,
            check_spec,
            open_source,
            scheme_of,
        )
        from autopilot_bridge.camera.video import VideoSourceError

        try:
            if camera is None:  # the field file's (a camera component beside a real autopilot), else the link's
                camera = fs.camera if fs is not None and fs.camera else "mavlink"
            check_spec(camera if camera != "video" else "udp://")
        except CameraSpecError as e:
            raise typer.BadParameter(str(e), param_hint="--camera") from e
        try:  # before anything flies: a policy that cannot serve this field says so now
            pol = flight_policy(policy, checkpoint, grid, seed)
        except PolicyUnfit as e:
            raise typer.BadParameter(str(e), param_hint="--policy") from e

        out.mkdir(parents=True, exist_ok=True)
        config = {"connect": address, "field": None if field is None else str(field), "grid": grid.to_dict(),
                  "origin": [origin.lat_deg, origin.lon_deg, origin.alt_m], "policy": pol.name,
                  "checkpoint": None if checkpoint is None else str(checkpoint), "altitude": altitude,
                  "max_moves": max_moves, "on_abort": on_abort.value, "field_edge": edge, "camera": camera,
                  "autopilot": autopilot.lower(), "set_failsafe": set_failsafe}
        if doc is not None and field is None:
            config["field"] = doc.config.get("field")
        if pf is not None:
            config["polygon"] = {"source": pf.source, "heading_deg": pf.heading_deg}
        from missions.keys import KeyFileError, read_signing_key

        try:
            key = read_signing_key(signing_key_file) if signing_key_file is not None else None
        except KeyFileError as e:
            raise typer.BadParameter(str(e), param_hint="--signing-key-file") from e
        config["signing"] = key is not None
        if camera == "video":
            if fs is None or fs.video_uri is None:
                raise typer.BadParameter("video: the field file names no video stream (start `uavsearch sitl "
                                         "--video-port 5600`), or give its URL", param_hint="--camera")
            camera = fs.video_uri
        frames = None
        if scheme_of(camera)[0] != "mavlink":  # a video stream needs no link: opened (or refused) first
            sdp = video_sdp if video_sdp is not None else (fs.video_sdp if fs is not None else None)
            try:
                frames = open_source(camera, None, sdp=sdp)
            except VideoSourceError as e:
                raise typer.BadParameter(str(e), param_hint="--camera") from e
        config["camera"] = camera
        resumes = [] if doc is None else doc.resumes
        tlog_name = "companion.tlog" if doc is None else f"companion-resumed-{len(resumes) + 1}.tlog"
        link = VehicleLink(address, tlog=out / tlog_name if tlog else None,
                           tlog_meta=stamp(config, seed, kind="companion tlog"), signing_key=key,
                           dialect=autopilot.lower())
        typer.echo(f"policy {pol.name} on a {grid.width} x {grid.height} field, {grid.n_targets} targets "
                   f"({grid.motion}); connecting to {address} (on abort: {on_abort.value})")
        try:  # the camera before anything flies: none answering is one clear line, nothing armed
            if frames is None:
                frames = open_source(camera, link, link_address=address, signing_key=key, timeout_s=CAMERA_TIMEOUT_S,
                                     tlog=out / "camera.tlog" if tlog and camera != "mavlink" else None)
        except CameraNotFound as e:
            link.close()
            typer.echo(f"error: {e}", err=True)
            raise typer.Exit(1) from None
        except BaseException:
            link.close()
            raise
        target = getattr(frames, "target", None)
        typer.echo(f"camera: {target.describe() if target is not None else camera}")
        try:
            with FlightProgress(f"search ({pol.name})") as progress:
                spec = SearchSpec(origin, grid, altitude, max_moves=max_moves, field_edge=edge,
                                  set_failsafe=set_failsafe, launch_ne=fs.launch_ne if fs is not None else None,
                                  **({} if pf is None else field_spec(pf)))
                service = PolicyService(link, pol, spec, seed,
                                        on_progress=progress, frames=frames)
                if hasattr(frames, "clock"):  # a stream's unstamped frames: on the vehicle's clock
                    frames.clock = lambda: service.intake.sim_time_s
                go_on = None
                if doc is not None:
                    try:
                        loop = load(out, service)
                    except JournalError as e:
                        raise typer.BadParameter(str(e), param_hint="--resume") from e
                    typer.echo(f"resuming the search journaled in {doc.path}: {loop.move} moves flown, "
                               f"{len(service.log.believed_found)}/{grid.n_targets} found, next from cell {loop.cell}")

                    def go_on() -> tuple[int, np.ndarray, float]:
                        r = rejoin(service, doc, loop)
                        journal.resumes.append(r.to_dict())
                        near = "" if r.off_setpoint_m is None else f", {r.off_setpoint_m:.1f} m from its last setpoint"
                        typer.echo(f"vehicle {r.how} (found {'armed' if r.armed_found else 'disarmed'} in "
                                   f"{r.mode_found or '?'}{near}); next decision at {r.t_k:.1f} s, "
                                   f"{r.gap_s:.1f} s (simulated) after the journal")
                        return loop.move, np.array(loop.cell), r.t_k
                journal = Journal(out, service, config, resumes)
                service.journal = journal
                end = guarded_search(service, link, on_abort, abort_timeout, hold_time, echo=typer.echo,
                                     move_timeout_s=move_timeout, rejoin=go_on)
                journal.end(end.to_dict(), ended=end.exit_code in (EXIT_OK, EXIT_SHORT))
        finally:
            frames.close()
            link.close()
        log = end.log
        save_log(log, out / "search_log.json", outcome=end.to_dict(), provenance=stamp(config, seed),
                 resumes=journal.resumes, journal={"writes": journal.writes, "write_s": round(journal.write_s, 3)})
        moves = max(len(log.cells) - 1, 0)
        if log.cells:
            from missions.run_plot import plot_decisions

            how = "" if end.cause is None else f" ({end.cause[:60]})"
            plot_decisions(out / "search.png", grid, log.cells, log.believed_found, log.posterior_sd_m,
                           f"{pol.name}: {moves} moves, {len(log.believed_found)}/{grid.n_targets} found{how}")
        typer.echo(f"{moves} moves, {len(log.believed_found)}/{grid.n_targets} targets believed found; log and plot in {out}")
        if end.exit_code == EXIT_SHORT:
            typer.echo(f"warning: {end.cause}", err=True)
        elif end.exit_code != EXIT_OK:
            typer.echo(f"error: {end.cause}", err=True)
        raise typer.Exit(end.exit_code)

