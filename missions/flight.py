"""The main job: a simulated vehicle, the policy service flying a search over MAVLink, and a
report scored against the simulator's truth (which only this module reads)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_write_json, stamp
from sim.gridworld import GridConfig


def _plot(out: Path, grid: GridConfig, targets: np.ndarray, cells: list, track: np.ndarray, title: str,
          mask: np.ndarray | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    ax.set_xlim(-0.5, grid.width - 0.5)
    ax.set_ylim(grid.height - 0.5, -0.5)
    ax.set_xticks(range(grid.width))
    ax.set_yticks(range(grid.height))
    ax.grid(True, color="0.85")
    ax.set_facecolor((0.86, 0.93, 0.82))
    if mask is not None:  # a real field's cells not searched (off it, or in a no-fly zone): grey
        ax.imshow(np.where(np.asarray(mask)[..., None], [0.86, 0.93, 0.82, 0.0], [0.55, 0.55, 0.55, 0.8]),
                  extent=(-0.5, grid.width - 0.5, grid.height - 0.5, -0.5), interpolation="nearest", zorder=0)
    c = np.array(cells)
    if len(track):
        ax.plot(track[:, 0], track[:, 1], "-", color="tab:blue", alpha=0.45, lw=1, label="true track (physics)")
    ax.plot(c[:, 0], c[:, 1], "o-", color="tab:blue", ms=3, lw=1.5, label="decisions (cells)")
    ax.plot(c[0, 0], c[0, 1], "^", color="tab:orange", ms=10, label="start")
    ax.plot(c[-1, 0], c[-1, 1], "s", color="tab:green", ms=10, label="end")
    ax.plot(targets[:, 0], targets[:, 1], "X", color="tab:red", ms=12, label="targets (truth)")
    from missions.run_plot import save_figure

    save_figure(fig, ax, out, title, fontsize=10)


@contextmanager
def _nothing() -> Iterator[None]:
    yield None


def truly_met(track: np.ndarray, herd: np.ndarray) -> list[bool]:
    """track (T, 2) true vehicle cells, herd (T, R, 2) true target cells at the same instants:
    per target, was the vehicle ever within half a cell (each axis) of it at the same time?"""
    if not len(track):
        return [False] * herd.shape[1]
    near = np.max(np.abs(track[:, None, :] - herd), axis=2) < 0.5  # (T, R)
    return near.any(axis=0).tolist()


#: the 95 % point of chi-square with 2 degrees of freedom
CHI2_2_95 = 5.991464547107979


def grid_moves(policy, episode, grid: GridConfig, seed: int) -> int:
    """Moves the same policy takes on the same episode in the grid world (the flight's yardstick)."""
    import dataclasses

    from policy.base import observe
    from sim.gridworld import BatchGridWorld

    if grid.levels > 1 and episode.cfg != grid:  # the SITL's field is the levels' single-height twin (field_grid): same cells
        episode = dataclasses.replace(episode, cfg=grid)
    policy.reset(grid, 1, seed, episode if policy.needs_truth else None)
    world = BatchGridWorld(episode, seed, off_map=getattr(policy, "off_map", "random"))
    while not world.done.all():
        world.step(policy.act(observe(world)))
    return int(world.t[0])


def field_grid(grid: GridConfig) -> GridConfig:
    """The field the SITL simulates for a search grid: the grid itself, or with altitude levels
    its single-height twin (the field, the targets and their placement do not depend on the
    levels the companion flies: the same seed puts the targets on the same cells)."""
    import dataclasses

    return grid if grid.levels == 1 else dataclasses.replace(grid, levels=1, detection=None)


def consistency(times_s: list, means: list, covs: list, truth: np.ndarray) -> dict[str, Any]:
    """NEES of the horizontal position posterior against the simulator's truth at the same
    simulated times (truth: (n, 3) rows of t, north, east in the field frame)."""
    if not times_s or len(truth) < 2:
        return {"nees": [], "nees_mean": None, "inside_95": None}
    t = np.asarray(times_s)
    true_ne = np.stack([np.interp(t, truth[:, 0], truth[:, 1]), np.interp(t, truth[:, 0], truth[:, 2])], axis=1)
    err = np.asarray(means) - true_ne
    nees = np.einsum("ki,kij,kj->k", err, np.linalg.inv(np.asarray(covs)), err)
    return {"nees": nees.tolist(), "nees_mean": float(nees.mean()), "inside_95": float(np.mean(nees < CHI2_2_95)),
            "true_ne": true_ne.tolist()}


def offsets_from_cells(times_s: list, cells: list, truth: np.ndarray) -> list:
    """Per decision: where the vehicle truly was relative to its cell's centre (north, east m)."""
    from sim.gridworld import cell_to_ned

    if not times_s or len(truth) < 2:
        return []
    t = np.asarray(times_s)
    true_ne = np.stack([np.interp(t, truth[:, 0], truth[:, 1]), np.interp(t, truth[:, 0], truth[:, 2])], axis=1)
    centres = np.array([cell_to_ned(np.array(c)) for c in cells])
    return np.round(true_ne - centres, 3).tolist()


def _truth_sitl(cfg):
    """The SITL with the scorer's view of the truth: its true position recorded every tick
    (simulated time, north, east in the field frame). Never given to the companion."""
    from sim.mavlink import Sitl

    class TruthSitl(Sitl):
        def __init__(self, cfg) -> None:
            super().__init__(cfg)
            self.truth: list[tuple[float, float, float]] = []
            self.height: list[float] = []  # true height over the field at the same ticks

        def step(self) -> None:
            super().step()
            p = self.model.state.position_ned
            self.truth.append((self.t, float(p[0] + self.spawn_ne[0]), float(p[1] + self.spawn_ne[1])))
            self.height.append(float(-p[2]))

    return TruthSitl(cfg)


def gps_config(sigma_m: float | None):
    """The simulated receiver, its error (white and bias together) scaled to a total horizontal
    sd of sigma_m per axis (None: the default receiver, 0.92 m)."""
    from sim.vehicle.gps import GpsConfig

    gps = GpsConfig()
    if sigma_m is None:
        return gps
    if not sigma_m > 0:
        raise ValueError(f"GPS sigma must be > 0 m (got {sigma_m})")
    k = sigma_m / float(np.hypot(gps.sigma_h, gps.bias_sigma_h))
    return GpsConfig(sigma_h=gps.sigma_h * k, bias_sigma_h=gps.bias_sigma_h * k)


def fly_search(out: Path, seed: int = 0, speedup: float = 8.0, checkpoint: Path | None = None,
               grid: GridConfig | None = None, instance: int = 0, max_moves: int | None = None,
               policy: str | None = None, on_abort: str = "rtl", progress: bool = False,
               physics: str = "pybullet", gps_sigma_m: float | None = None, visit_map: str = "probabilistic",
               free_ports: bool = False, plot: bool = True, lockstep: bool = True,
               camera: str = "mavlink", autopilot: str = "ours", field: Any = None) -> dict[str, Any]:
    """Start SITL in-process, fly a policy (default: the best shipped one) over MAVLink, write
    report + plot + tlog. Any failure or Ctrl-C brings the vehicle down first (missions.guarded);
    report['outcome'] says how the flight ended, report['error'] what stopped it, if anything.

    The policy and the companion's link exist before the vehicle starts, so the flight's
    simulated schedule does not depend on how long loading took. The report compares the flight
    with the same policy on the same episode in the grid world, and the position posterior with
    the truth (NEES). free_ports: ports the OS hands out (parallel flights beside other tests).
    camera: "mavlink" (the vehicle's MAVLink camera) or "video" (its RTP/H.264 stream on a free
    port, decoded by autopilot_bridge.camera.video; with lockstep, captures are asked for over
    MAVLink, which holds the SITL at each, as with the MAVLink camera).

    field: a real field (`sim.field.PolygonField`, our SITL only): the SITL renders it and places
    home and targets on its searchable cells, the companion searches its mask in its grid's
    frame with its fence uploaded (margin `fence.FIELD_MARGIN_M`), and the report counts every
    setpoint the vehicle heard outside that fence (its tlog), every place a setpoint meant that
    is off the field or in a no-fly zone, and every tick the vehicle truly was (`field_checks`);
    the grid is the field's (`grid`'s size is replaced)."""
    if camera not in ("mavlink", "video"):
        raise ValueError(f"camera must be 'mavlink' or 'video' (got {camera!r})")
    from autopilot_bridge.link.connection import VehicleLink
    from autopilot_bridge.service.policy_service import PolicyService, SearchSpec, save_log
    from missions.flight_policy import flight_policy
    from missions.guarded import EXIT_OK, EXIT_SHORT, guarded_search
    from missions.progress import FlightProgress
    from policy.groundtruth import optimal_lengths
    from sim.mavlink import SitlConfig

    grid = grid or GridConfig()
    if field is not None:
        from missions.field_run import on_polygon_grid

        if autopilot != "ours":
            raise ValueError("a polygon field is flown on our SITL vehicle only (autopilot 'ours')")
        grid = on_polygon_grid(field, grid)
    pol = flight_policy(policy, checkpoint, grid, seed)  # before anything starts: can it fly this field?
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ports = {}
    if free_ports:
        ports = dict(zip(("api_local_port", "api_remote_port", "gcs_local_port", "gcs_remote_port"),
                         _free_udp_ports(4), strict=True))
    gps = gps_config(gps_sigma_m)
    from sim.mavlink.video import VideoConfig

    video = VideoConfig(port=_free_udp_ports(1)[0]) if camera == "video" else VideoConfig()
    cfg = SitlConfig(instance=instance, speedup=speedup, physics=physics, camera=True, grid=field_grid(grid),
                     episode_seed=seed, seed=seed, tlog=out / "flight.tlog", gcs_link=True, gps=gps,
                     companion_lockstep=lockstep, video=video, **ports,
                     **({} if field is None else {"home": field.origin, "polygon": field}))
    held = ExitStack()
    frames = None
    if autopilot != "ours":  # a real autopilot binary flies our world (sim.bridges)
        sitl, link, frames = _real_autopilot(held, autopilot, speedup, field_grid(grid), seed, gps, cfg.field_edge, out)
        lockstep = False
    else:
        link = VehicleLink(f"udpin:0.0.0.0:{cfg.api_ports[1]}", tlog=None)
        try:
            sitl = _truth_sitl(cfg).start()
        except BaseException:
            link.close()
            raise
    track: list[np.ndarray] = []
    herd: list[np.ndarray] = []  # the targets' cells at the same instants as track
    stop = threading.Event()

    def watch() -> None:  # the scorer's view of the truth, never given to the service
        while not stop.is_set():
            t = sitl.t
            herd.append(sitl.target_cells(t).copy())
            track.append(sitl.vehicle_cell().copy())
            time.sleep(0.05)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    area = fence = None
    if field is not None:
        from missions.field_run import field_spec

        area, fence = field_spec(field).values()
    spec = SearchSpec(origin=sitl.field_origin, grid=grid, max_moves=max_moves, visit_map=visit_map,
                      field_edge=cfg.field_edge and field is None, set_failsafe=autopilot != "ours",
                      area=area, fence=fence,
                      # a real autopilot's home is its GPS fix at arming: the pad it stands on is given
                      launch_ne=None if autopilot == "ours" else tuple(float(v) for v in sitl.world.scene.spawn_ne))
    t0 = time.monotonic()
    try:
        if video.enabled:
            from autopilot_bridge.camera import MavlinkCamera
            from autopilot_bridge.camera.video import VideoSource

            # a timed capture asked of the camera component: what holds a lockstep SITL at at_s
            ask = MavlinkCamera(link).ask

            frames = VideoSource(f"udp://:{video.port}", sitl.video.write_sdp(out / "camera.sdp"),
                                 asker=ask if lockstep else None)
        with FlightProgress(f"flight ({pol.name})") if progress else _nothing() as bar:
            service = PolicyService(link, pol, spec, seed=seed, on_progress=bar, frames=frames)
            end = guarded_search(service, link, on_abort)
        log = end.log
        error = None if end.exit_code in (EXIT_OK, EXIT_SHORT) else end.cause
    finally:
        stop.set()
        watcher.join()
        sim_time = sitl.t
        link.close()
        if frames is not None:
            frames.close()
        sitl.stop()
        held.close()
    targets = sitl.episode.targets[0]
    n = min(len(track), len(herd))
    tr = np.array(track[:n]) if n else np.zeros((0, 2))
    # truly recovered: the vehicle's true position came within half a cell of the target's
    # centre at the same time (a moving target is met where it is then, not where it was)
    truly = truly_met(tr, np.array(herd[:n]) if n else np.zeros((0, len(targets), 2)))
    moves = max(len(log.cells) - 1, 0)
    optimal = int(optimal_lengths(sitl.episode)[0])
    try:
        in_grid: int | None = grid_moves(flight_policy(policy, checkpoint, grid, seed), sitl.episode, grid, seed)
    except Exception as e:  # noqa: BLE001 - a policy that fails in the grid world too: the report says so
        in_grid = None
        log_grid_error = f"{type(e).__name__}: {e}"
    else:
        log_grid_error = None
    truth = np.array(sitl.truth) if sitl.truth else np.zeros((0, 3))
    checks = None
    if field is not None:
        from missions.field_checks import field_checks

        checks = field_checks(field, fence, out / "flight.tlog", sitl.spawn_ne, truth, sitl.vehicle.counters,
                              log.setpoint_field_ne)
        from autopilot_bridge.service.fence import FIELD_MARGIN_M

        checks["fence_margin_m"] = FIELD_MARGIN_M
        # the companion's posterior is in the grid's frame (ahead, right): the truth too, for NEES and offsets
        truth = truth.copy()
        truth[:, 1:3] = area.frame.ned_to_grid(truth[:, 1:3])
    cons = consistency(log.times_s, log.posterior_mean_ne, log.posterior_cov_ne, truth)
    save_log(log, out / "search_log.json", outcome=end.to_dict(), true_ne=cons.get("true_ne", []))
    report = stamp(grid.to_dict(), seed, sitl={"instance": instance, "speedup": speedup, "physics": physics,
                                               "autopilot": autopilot},
                   policy=pol.name, outcome=end.to_dict(),
                   moves=moves, optimal_moves=optimal, ratio_to_optimal=moves / max(optimal, 1),
                   grid_moves=in_grid, flight_grid_ratio=None if in_grid is None else moves / max(in_grid, 1),
                   grid_error=log_grid_error, visit_map=visit_map,
                   gps={"sigma_h": gps.sigma_h, "bias_sigma_h": gps.bias_sigma_h, "bias_tau_s": gps.bias_tau_s},
                   decision_period_s=spec.decision_period_s, schedule_slips=log.schedule_slips,
                   late_frames=log.late_frames, late_inputs=log.late_inputs, cells=[list(c) for c in log.cells],
                   offset_from_cell_m=offsets_from_cells(log.times_s, log.cells, truth),
                   true_height_m=(np.round(np.interp(log.times_s, truth[:, 0], sitl.height[:len(truth)]), 3).tolist()
                                  if len(truth) and log.times_s else []),
                   nees_mean=cons["nees_mean"], nees_inside_95=cons["inside_95"], nees=cons["nees"],
                   camera=camera, video_frames_dropped=sitl.video.frames_dropped if sitl.video else None,
                   sitl_errors=len(sitl.errors), lockstep=lockstep, lockstep_timeouts=sitl.lockstep_timeouts,
                   targets=int(grid.n_targets), believed_found=len(log.believed_found),
                   truly_found=int(sum(truly)), frames=log.frames, frames_missing=log.frames_missing,
                   mean_posterior_sd_m=float(np.mean(log.posterior_sd_m)) if log.posterior_sd_m else None,
                   decision_ms_p50=float(np.percentile(log.decision_ms, 50)) if log.decision_ms else None,
                   decision_ms_p99=float(np.percentile(log.decision_ms, 99)) if log.decision_ms else None,
                   simulated_s=sim_time, wall_s=time.monotonic() - t0, error=error,
                   # simulated seconds from the first decision to the last: the search's flight time
                   search_s=float(log.times_s[-1] - log.times_s[0]) if log.times_s else None,
                   levels_flown=log.levels_flown, camera_height_m=log.camera_height_m,
                   tlog=str(out / ("flight.tlog" if autopilot == "ours" else "companion.tlog")),
                   **({} if checks is None else {"field": {"source": field.source, "heading_deg": field.heading_deg,
                                                           "searchable_cells": int(area.mask.sum())},
                                                 "field_checks": checks}),
                   plot=str(out / "search.png"))
    atomic_write_json(out / "report.json", report)
    if plot and log.cells:
        from dataclasses import asdict

        from missions.flight_report import write_report

        path = np.stack([truth[::5, 2] / 2.0, -truth[::5, 1] / 2.0], axis=1) if len(truth) else tr
        _plot(out / "search.png", grid, targets, log.cells, path,
              f"{moves} moves (grid world {in_grid}, optimal {optimal}); found {sum(truly)}/{grid.n_targets} (truth)",
              mask=None if area is None else area.mask)
        frames = list(service.kept_frames)
        if service.last_frame is not None and (not frames or frames[-1][0] != service.last_frame[0]):
            frames.append(service.last_frame)
        write_report(out, report, {**asdict(log), "true_ne": cons.get("true_ne", [])}, service.pmap.visited,
                     service.pmap.met, targets, frames)
    return report


def _real_autopilot(held: ExitStack, autopilot: str, speedup: float, grid: GridConfig, seed: int, gps: Any,
                    field_edge: bool, out: Path) -> tuple[Any, Any, Any]:
    """The real autopilot's world on an instance this flight holds, started, with the
    companion's link and camera: (the scorer's view of it, the link, the frame source). The
    companion connects before the binary starts, so it hears from the first heartbeat."""
    from autopilot_bridge.camera import open_source
    from autopilot_bridge.link.connection import VehicleLink
    from missions.autopilot_flight import WorldVehicle, hold_instance
    from sim.bridges.world import AutopilotWorld, AutopilotWorldConfig

    instance = held.enter_context(hold_instance())
    world = AutopilotWorld(AutopilotWorldConfig(
        autopilot=autopilot, instance=instance, speedup=speedup, grid=grid, episode_seed=seed, seed=seed, gps=gps,
        field_edge=field_edge, gcs_port=None))
    link = VehicleLink(world.companion_address().replace("udpin:127.0.0.1:", "udpin:0.0.0.0:"),
                       tlog=out / "companion.tlog")
    try:
        world.start()
        frames = open_source(world.camera_address(), link, timeout_s=30.0, tlog=out / "camera.tlog")
    except BaseException:
        link.close()
        world.stop()
        held.close()
        raise
    return WorldVehicle(world), link, frames


def _free_udp_ports(n: int) -> list[int]:
    """n distinct UDP ports the OS has just handed out."""
    import socket

    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()
