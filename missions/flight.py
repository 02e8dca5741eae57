"""The main job: a simulated vehicle, the policy service flying a search over MAVLink, and a
report scored against the simulator's truth (which only this module reads)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open, atomic_write_json, stamp
from sim.gridworld import GridConfig


def _plot(out: Path, grid: GridConfig, targets: np.ndarray, cells: list, track: np.ndarray, title: str) -> None:
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
    c = np.array(cells)
    if len(track):
        ax.plot(track[:, 0], track[:, 1], "-", color="tab:blue", alpha=0.45, lw=1, label="true track (physics)")
    ax.plot(c[:, 0], c[:, 1], "o-", color="tab:blue", ms=3, lw=1.5, label="decisions (cells)")
    ax.plot(c[-1, 0], c[-1, 1], "s", color="tab:green", ms=10, label="end")
    ax.plot(targets[:, 0], targets[:, 1], "X", color="tab:red", ms=12, label="targets (truth)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    with atomic_open(out, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)


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


def fly_search(out: Path, seed: int = 0, speedup: float = 8.0, checkpoint: Path | None = None,
               grid: GridConfig | None = None, instance: int = 0, max_moves: int | None = None,
               policy: str | None = None, on_abort: str = "rtl", progress: bool = False,
               physics: str = "pybullet") -> dict[str, Any]:
    """Start SITL in-process, fly a policy (default: the best shipped one) over MAVLink, write
    report + plot + tlog. Any failure or Ctrl-C brings the vehicle down first (missions.guarded);
    report['outcome'] says how the flight ended, report['error'] what stopped it, if anything."""
    from autopilot_bridge.link import VehicleLink
    from autopilot_bridge.service import PolicyService, SearchSpec, save_log
    from missions.flight_policy import flight_policy
    from missions.guarded import EXIT_OK, EXIT_SHORT, guarded_search
    from missions.progress import FlightProgress
    from policy.groundtruth import optimal_lengths
    from sim.mavlink import Sitl, SitlConfig

    grid = grid or GridConfig()
    pol = flight_policy(policy, checkpoint, grid, seed)  # before anything starts: can it fly this field?
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = SitlConfig(instance=instance, speedup=speedup, physics=physics, camera=True, grid=grid,
                     episode_seed=seed, seed=seed, tlog=out / "flight.tlog", gcs_link=True)
    sitl = Sitl(cfg).start()
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
    link = VehicleLink(f"udpin:0.0.0.0:{cfg.api_ports[1]}", tlog=None)
    spec = SearchSpec(origin=sitl.field_origin, grid=grid, max_moves=max_moves)
    t0 = time.monotonic()
    try:
        with FlightProgress(f"flight ({pol.name})") if progress else _nothing() as bar:
            service = PolicyService(link, pol, spec, seed=seed, on_progress=bar)
            end = guarded_search(service, link, on_abort)
        log = end.log
        error = None if end.exit_code in (EXIT_OK, EXIT_SHORT) else end.cause
    finally:
        stop.set()
        watcher.join()
        sim_time = sitl.t
        link.close()
        sitl.stop()
    targets = sitl.episode.targets[0]
    n = min(len(track), len(herd))
    tr = np.array(track[:n]) if n else np.zeros((0, 2))
    # truly recovered: the vehicle's true position came within half a cell of the target's
    # centre at the same time (a moving target is met where it is then, not where it was)
    truly = truly_met(tr, np.array(herd[:n]) if n else np.zeros((0, len(targets), 2)))
    moves = max(len(log.cells) - 1, 0)
    optimal = int(optimal_lengths(sitl.episode)[0])
    save_log(log, out / "search_log.json", outcome=end.to_dict())
    report = stamp(grid.to_dict(), seed, sitl={"instance": instance, "speedup": speedup, "physics": physics},
                   policy=pol.name, outcome=end.to_dict(),
                   moves=moves, optimal_moves=optimal, ratio_to_optimal=moves / max(optimal, 1),
                   targets=int(grid.n_targets), believed_found=len(log.believed_found),
                   truly_found=int(sum(truly)), frames=log.frames, frames_missing=log.frames_missing,
                   mean_posterior_sd_m=float(np.mean(log.posterior_sd_m)) if log.posterior_sd_m else None,
                   decision_ms_p50=float(np.percentile(log.decision_ms, 50)) if log.decision_ms else None,
                   decision_ms_p99=float(np.percentile(log.decision_ms, 99)) if log.decision_ms else None,
                   simulated_s=sim_time, wall_s=time.monotonic() - t0, error=error,
                   tlog=str(out / "flight.tlog"), plot=str(out / "search.png"))
    atomic_write_json(out / "report.json", report)
    if log.cells:
        _plot(out / "search.png", grid, targets, log.cells, tr,
              f"{moves} moves (optimal {optimal}); found {sum(truly)}/{grid.n_targets} (truth)")
    return report
