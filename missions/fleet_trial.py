"""A scored fleet flight: our SITL fleet (sim.mavlink.SitlFleet, one process, one physics step)
on one field, the fleet companion (missions.fleet_flight) flying it over real MAVLink on UDP
loopback, and a report scored against the simulator's truth, which only this module reads.

Scored: targets truly found (a vehicle's true position within half a cell of the target's,
either axis), the least true horizontal distance between two airborne vehicles, and the
flight's makespan (the team's rounds) over the team grid world's on the same episode, starts,
planner and seed (policy.team.runner's world). `cut`: the link of one vehicle goes silent at a
round (a FaultProxy between it and the companion cut: a radio out of range), so the companion
loses it, its own offboard-loss failsafe lands it and the others finish the search.
"""

from __future__ import annotations

import threading
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_write_json, stamp
from sim.gridworld import GridConfig

#: the field origin the trials fly (the SITL's default: Bristol)
ORIGIN = (51.4545, -2.5879, 30.0)


def grid_makespan(grid: GridConfig, seed: int, n: int) -> int:
    """Joint steps the team belief planner takes on this seed's episode in the team grid world."""
    from policy.team import make_team_policy, team_observe
    from sim.gridworld import sample_episodes
    from sim.gridworld.team import TeamGridWorld, team_starts

    ep = sample_episodes(grid, 1, seed)
    pol = make_team_policy("belief")
    pol.reset(grid, 1, n, seed)
    world = TeamGridWorld(ep, team_starts(ep, n), seed)
    while not world.done.all():
        world.step(pol.act(team_observe(world)))
    return int(world.t[0])


def fly_fleet_trial(out: Path, vehicles: int = 3, grid: GridConfig | None = None, seed: int = 0,
                    speedup: float = 12.0, physics: str = "pybullet", cut: tuple[int, int] | None = None,
                    move_timeout_s: float = 20.0, plot: bool = True, echo=lambda m: None,
                    height_step_m: float | None = None, kill: tuple[int, int] | None = None,
                    autopilot: str = "ours") -> dict[str, Any]:
    """Fly one fleet trial; write OUT/report.json (and the companion's logs and plot). cut:
    (vehicle, round) whose link is cut once the team has decided that many rounds; kill:
    (vehicle, round) force-disarmed then by a ground station on its GCS link (it falls).
    autopilot "ardupilot" / "px4": each vehicle a real ArduCopter / PX4 SITL flying a world of
    its own (sim.bridges) on the one episode, on an instance this trial holds (ports, system
    id), its camera a component on its own endpoint, its failsafe set by the companion."""
    from autopilot_bridge.link.connection import VehicleLink
    from autopilot_bridge.service.fleet import SAME_HEIGHT_M
    from autopilot_bridge.service.policy_service import SearchSpec
    from missions.fleet_flight import build_team, fly_fleet, save_fleet
    from missions.flight import _free_udp_ports, truly_met
    from sim.gridworld import sample_episodes
    from sim.gridworld.geodesy import HomePosition
    from sim.gridworld.team import team_starts
    from sim.mavlink import SitlConfig, SitlFleet
    from sim.mavlink.faultproxy import FaultProxy

    grid = grid or GridConfig(width=8, height=8, n_targets=3)
    from autopilot_bridge.service.fleet import HEIGHT_STEP_M

    height_step_m = HEIGHT_STEP_M if height_step_m is None else height_step_m
    if autopilot not in ("ours", "ardupilot", "px4"):
        raise ValueError(f"a fleet flies autopilot 'ours', 'ardupilot' or 'px4' (got {autopilot!r})")
    if autopilot != "ours" and (cut is not None or kill is not None or physics != "pybullet"):
        raise ValueError("a fleet of real autopilots flies the PyBullet body, with no cut or killed link (for now)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    starts = team_starts(sample_episodes(grid, 1, seed), vehicles)[0]
    origin = HomePosition(*ORIGIN)
    ports = _free_udp_ports(4 * vehicles) if autopilot == "ours" else []
    proxy: FaultProxy | None = None
    cfgs, addresses = [], []
    for i in range(vehicles if autopilot == "ours" else 0):
        local, listen, gcs_l, gcs_r = ports[4 * i:4 * i + 4]
        remote = listen
        if cut is not None and cut[0] == i:
            proxy = FaultProxy(local, listen).start()
            remote = proxy.vehicle_side_port
        cfgs.append(SitlConfig(instance=i, speedup=speedup, physics=physics, camera=True, grid=grid, home=origin,
                               episode_seed=seed, seed=seed + i, spawn_cell=(int(starts[i][0]), int(starts[i][1])),
                               api_local_port=local, api_remote_port=remote, gcs_local_port=gcs_l,
                               gcs_remote_port=gcs_r))
        addresses.append(f"udpin:0.0.0.0:{listen}")
    links = [VehicleLink(a, tlog=None) for a in addresses]
    fleet = None
    track: list[list[np.ndarray]] = [[] for _ in range(vehicles)]
    stop = threading.Event()
    held = ExitStack()
    try:
        if autopilot == "ours":
            fleet = SitlFleet(cfgs)
            specs = [SearchSpec(origin=fleet[i].field_origin, grid=grid, field_edge=cfgs[i].field_edge,
                                altitude_m=3.5 + i * height_step_m) for i in range(vehicles)]
            team, services = build_team(links, specs, seed)
            fleet.start()
        else:
            fleet = _AutopilotFleet(held, autopilot, vehicles, grid, origin, seed, starts, speedup)
            links, frames = fleet.links, fleet.frames
            specs = [SearchSpec(origin=fleet[i].field_origin, grid=grid, field_edge=True, set_failsafe=True,
                                altitude_m=3.5 + i * height_step_m, launch_ne=fleet[i].launch_ne)
                     for i in range(vehicles)]
            team, services = build_team(links, specs, seed, frames=frames)
        min_sep = [float("inf")]
        min_level = [float("inf")]
        min_3d = [float("inf")]  # the least distance in space between two airborne vehicles  # the same, between vehicles within SAME_HEIGHT_M of one height
        closest: list = []  # (simulated s, vehicle, vehicle, field NE + height of each) at the least

        def watch() -> None:  # the scorer's truth, never given to the companion
            while not stop.is_set():
                air = []
                for i in range(vehicles):
                    s = fleet[i]
                    track[i].append(s.vehicle_cell().copy())
                    p = s.model.state.position_ned
                    if -p[2] > 1.0:
                        air.append((i, np.array([p[0] + s.spawn_ne[0], p[1] + s.spawn_ne[1], -p[2]])))
                for a in range(len(air)):
                    for b in range(a + 1, len(air)):
                        d = float(np.hypot(*(air[a][1][:2] - air[b][1][:2])))
                        min_3d[0] = min(min_3d[0], float(np.linalg.norm(air[a][1] - air[b][1])))
                        if abs(air[a][1][2] - air[b][1][2]) < SAME_HEIGHT_M:
                            min_level[0] = min(min_level[0], d)
                        if d < min_sep[0]:
                            min_sep[0] = d
                            closest[:] = [round(fleet.t, 2), air[a][0], air[b][0],
                                          np.round(air[a][1], 2).tolist(), np.round(air[b][1], 2).tolist()]
                if kill is not None and team.log.rounds >= kill[1] and not killed.is_set():
                    killed.set()
                    threading.Thread(target=_force_disarm, args=(cfgs[kill[0]],), daemon=True).start()
                    echo(f"vehicle {kill[0]} force-disarmed at round {team.log.rounds}")
                if proxy is not None and cut is not None and team.log.rounds >= cut[1] and not proxy_cut.is_set():
                    proxy.cut()
                    proxy_cut.set()
                    echo(f"link of vehicle {cut[0]} cut at round {team.log.rounds}")
                time.sleep(0.02)

        proxy_cut, killed = threading.Event(), threading.Event()
        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        t0 = time.monotonic()
        end = fly_fleet(team, services, "land", 60.0, move_timeout_s, echo)
        wall = time.monotonic() - t0
        # the cut vehicle's own failsafe lands it: wait (bounded) for its touchdown
        deadline = time.monotonic() + 60.0 / max(speedup, 1.0) + 10.0
        while time.monotonic() < deadline and any(fleet[i].model.state.armed for i in range(vehicles)):
            time.sleep(0.1)
        stop.set()
        watcher.join()
        armed_after = [bool(fleet[i].model.state.armed) for i in range(vehicles)]
        heights = [float(-fleet[i].model.state.position_ned[2]) for i in range(vehicles)]
        sim_s = fleet.t
    finally:
        stop.set()
        for link in links:
            link.close()
        if fleet is not None:
            fleet.stop()
        held.close()
        if proxy is not None:
            proxy.stop()
    targets = fleet[0].episode.targets[0]
    n = min(len(tr) for tr in track)
    tr = np.stack([np.array(t[:n]) for t in track], axis=1) if n else np.zeros((0, vehicles, 2))  # (T, N, 2)
    herd = np.broadcast_to(targets[None].astype(float), (max(n, 1), len(targets), 2))[:n]
    truly = np.zeros(len(targets), bool)
    for i in range(vehicles):
        truly |= np.array(truly_met(tr[:, i], herd), bool)
    in_grid = grid_makespan(grid, seed, vehicles)
    log = end.team.log
    config = {"kill": None if kill is None else list(kill), "vehicles": vehicles,
              **({} if autopilot == "ours" else {"autopilot": autopilot}), "grid": grid.to_dict(), "speedup": speedup, "physics": physics,
              "altitudes_m": [3.5 + i * height_step_m for i in range(vehicles)],
              "cut": None if cut is None else list(cut), "starts": starts.tolist(), "policy": "belief-team"}
    # the flight's makespan: the rounds that moved the team (the last round saw the last find and
    # moved no one), as the team world's joint steps
    moves = max(log.rounds - 1, 0) if end.team.finished else log.rounds
    report = stamp(config, seed, outcome=end.to_dict()["exit_code"], cause=end.cause, rounds=log.rounds,
                   moves=moves, grid_makespan=in_grid, flight_grid_ratio=moves / max(in_grid, 1),
                   believed_found=end.found, truly_found=int(truly.sum()), targets=int(grid.n_targets),
                   separation_refused=log.separation_refused,
                   min_separation_m=None if not np.isfinite(log.min_separation_m) else round(log.min_separation_m, 3),
                   min_true_separation_m=None if not np.isfinite(min_sep[0]) else round(min_sep[0], 3),
                   min_true_separation_same_height_m=None if not np.isfinite(min_level[0]) else round(min_level[0], 3),
                   min_true_distance_3d_m=None if not np.isfinite(min_3d[0]) else round(min_3d[0], 3),
                   closest_true=closest, min_setpoint_separation_m=None if not np.isfinite(log.min_setpoint_separation_m)
                   else round(log.min_setpoint_separation_m, 3),
                   duplicate_finds=log.duplicate_finds, lost={str(k): v[1] for k, v in log.lost.items()},
                   armed_after=armed_after, height_after_m=[round(h, 2) for h in heights],
                   schedule_slips=[s.log.schedule_slips for s in services],
                   late_frames=[s.log.late_frames for s in services], simulated_s=sim_s, wall_s=wall)
    atomic_write_json(out / "report.json", report)
    if plot:
        from missions.fleet_plot import plot_fleet

        save_fleet(out, end, services, config, seed, "")
        plot_fleet(out / "fleet.png", grid, [s.log.cells for s in services], log.finds,
                   f"{vehicles} vehicles, seed {seed}: {log.rounds} rounds (grid {in_grid}), "
                   f"{int(truly.sum())}/{grid.n_targets} truly found", [tr[:, i] for i in range(vehicles)], targets)
    return report


def _force_disarm(cfg) -> None:
    """A ground station on the vehicle's GCS link kills it: ARM_DISARM with the force magic."""
    from pymavlink import mavutil

    m = mavutil.mavlink
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{cfg.gcs_ports[1]}", source_system=255, source_component=190)
    try:
        if gcs.wait_heartbeat(timeout=5) is None:
            return
        for _ in range(3):
            gcs.mav.command_long_send(cfg.sysid, 1, m.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0)
            if gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.0) is not None:
                return
    finally:
        gcs.close()


class _WorldVehicle:
    """One real autopilot's world seen by the scorer as our SITL vehicle is (the names the
    trial's watcher reads: vehicle_cell, model.state, spawn_ne, field_origin, episode)."""

    def __init__(self, world: Any) -> None:
        self.world = world
        self.model = world.body
        self.spawn_ne = world.scene.spawn_ne
        self.field_origin = world.scene.field_origin
        self.episode = world.scene.episode
        self.launch_ne = tuple(float(v) for v in world.scene.spawn_ne)

    def vehicle_cell(self) -> np.ndarray:
        return self.world.vehicle_cell()


class _AutopilotFleet:
    """N real autopilot binaries (ArduCopter or PX4 SITL), each on a world of its own (one
    episode, the team's start cells, sensors seed + i), on instances held for the trial (PX4:
    1-9, its port plan); each companion link is opened before its binary starts (it hears the
    first heartbeat), then its camera component."""

    def __init__(self, held: ExitStack, autopilot: str, n: int, grid: GridConfig, origin: Any, seed: int,
                 starts: np.ndarray, speedup: float) -> None:
        from autopilot_bridge.camera import open_source
        from autopilot_bridge.link.connection import VehicleLink
        from missions.autopilot_flight import hold_instance
        from sim.bridges.world import AutopilotWorld, AutopilotWorldConfig

        self.worlds: list[Any] = []
        self.links: list[Any] = []
        self.frames: list[Any] = []
        try:
            for i in range(n):
                inst = held.enter_context(hold_instance())
                world = AutopilotWorld(AutopilotWorldConfig(
                    autopilot=autopilot, instance=inst, speedup=speedup, home=origin, grid=grid, episode_seed=seed,
                    seed=seed + i, gcs_port=None, spawn_cell=(int(starts[i][0]), int(starts[i][1]))))
                self.links.append(VehicleLink(world.companion_address().replace("udpin:127.0.0.1:", "udpin:0.0.0.0:"),
                                              tlog=None))
                world.start()  # a world that fails to start has stopped itself
                self.worlds.append(world)
                self.frames.append(open_source(world.camera_address(), self.links[-1], timeout_s=30.0))
        except BaseException:
            self.stop()
            raise
        self.vehicles = [_WorldVehicle(w) for w in self.worlds]

    def __getitem__(self, i: int) -> _WorldVehicle:
        return self.vehicles[i]

    @property
    def t(self) -> float:
        return min(w.t for w in self.worlds)

    def stop(self) -> None:
        for f in self.frames:
            f.close()
        for link in self.links:
            link.close()
        for w in self.worlds:
            w.stop()
