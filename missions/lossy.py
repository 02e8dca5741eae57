"""A search flown through a bad radio: the SITL vehicle, a seeded FaultProxy on its API link,
and the companion's PolicyService on the far side. The lossy-link test and benchmark share it;
it reports what the proxy did and what the link survived, and always lands (or says why not)."""

from __future__ import annotations

import socket
import time
from dataclasses import asdict
from typing import Any

from sim.gridworld import GridConfig
from sim.mavlink.faultproxy import FaultProxy, LinkFaults


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fly_lossy_search(faults: LinkFaults, seed: int = 0, max_moves: int | None = None, speedup: float = 10.0,
                     grid: GridConfig | None = None, instance: int = 30) -> dict[str, Any]:
    """Fly one search with every datagram of the companion's link through `faults` (both ways).
    Returns moves, frames, error (None when the search completed and the vehicle landed and
    disarmed), the proxy's fault counts and the link's retry/error counts."""
    from autopilot_bridge.link.connection import VehicleLink
    from autopilot_bridge.service.policy_service import PolicyService, SearchSpec
    from policy.nn import load_policy
    from sim.mavlink import Sitl, SitlConfig

    grid = grid or GridConfig()
    vport, cport = _free_port(), _free_port()
    proxy = FaultProxy(vport, cport, faults, seed=seed).start()
    cfg = SitlConfig(instance=instance, speedup=speedup, physics="pybullet", camera=True, grid=grid,
                     episode_seed=seed, seed=seed, gcs_link=False, api_local_port=vport,
                     api_remote_port=proxy.vehicle_side_port)
    sitl = Sitl(cfg).start()
    link = VehicleLink(f"udpin:127.0.0.1:{cport}")
    service = PolicyService(link, load_policy(None, cfg=grid),
                            SearchSpec(origin=sitl.field_origin, grid=grid, max_moves=max_moves,
                                       field_edge=cfg.field_edge), seed=seed)
    t0, error, log = time.monotonic(), None, service.log
    landed = False
    try:
        service.take_off()
        log = service.run()
        service.land()
        landed = True
    except Exception as e:  # noqa: BLE001 - reported; the vehicle is still brought down below
        error = f"{type(e).__name__}: {e}"
    finally:
        if not landed:
            try:
                service.land()
                landed = True
            except Exception as e:  # noqa: BLE001
                error = f"{error}; landing: {type(e).__name__}: {e}"
        armed = sitl.model.state.armed
        link.close()
        sitl.stop()
        proxy.stop()
    return {
        "seed": seed, "error": error, "armed_at_end": armed, "moves": max(len(log.cells) - 1, 0),
        "frames": log.frames, "frames_missing": log.frames_missing, "wall_s": time.monotonic() - t0,
        "faults": asdict(faults), "up": asdict(proxy.up.counts), "down": asdict(proxy.down.counts),
        "link": asdict(link.stats), "sitl_errors": len(sitl.errors),
    }


def upload_like_qgc(c, sysid: int, items, timeout: float = 0.4, tries: int = 15) -> int | None:
    """A ground station's mission upload as QGroundControl does it (pymavlink connection `c`):
    on silence, send the last message again (COUNT or the last item), up to `tries` times in a
    row; returns the MISSION_ACK type, or None when the vehicle went quiet."""
    from pymavlink import mavutil

    m_ = mavutil.mavlink
    last = c.mav.mission_count_encode(sysid, 1, len(items), m_.MAV_MISSION_TYPE_MISSION)
    c.mav.send(last)
    silent = 0
    while silent < tries:
        m = c.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], blocking=True, timeout=timeout)
        if m is None:
            silent += 1
            c.mav.send(last)
            continue
        silent = 0
        if m.get_type() == "MISSION_ACK":
            return m.type
        if 0 <= m.seq < len(items):
            last = items[m.seq]
            c.mav.send(last)
    return None


def lossy_mission_upload(faults: LinkFaults, seed: int, n_items: int = 8) -> dict[str, Any]:
    """Upload an n-item mission through `faults` to a kinematic SITL vehicle; the ACK, whether
    the vehicle holds every item, and the proxy's counts."""
    from pymavlink import mavutil

    from sim.mavlink import Sitl, SitlConfig

    vport, cport = _free_port(), _free_port()
    proxy = FaultProxy(vport, cport, faults, seed=seed).start()
    sitl = Sitl(SitlConfig(instance=31, speedup=4.0, physics="kinematic", gcs_link=False, api_local_port=vport,
                           api_remote_port=proxy.vehicle_side_port)).start()
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{cport}", source_system=255, source_component=190)
    t0 = time.monotonic()
    try:
        home = c.recv_match(type="HOME_POSITION", blocking=True, timeout=20)
        m_ = mavutil.mavlink
        lat0, lon0, d = home.latitude * 1e-7, home.longitude * 1e-7, 1 / 111_200.0
        items = [c.mav.mission_item_int_encode(
            sitl.cfg.sysid, 1, i, m_.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            m_.MAV_CMD_NAV_TAKEOFF if i == 0 else m_.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0.5, 0, float("nan"),
            int((lat0 + 2 * i * d) * 1e7), int(lon0 * 1e7), 3.5, m_.MAV_MISSION_TYPE_MISSION) for i in range(n_items)]
        ack = upload_like_qgc(c, sitl.cfg.sysid, items)
        held = [it.seq for it in sitl.vehicle.mission.items] == list(range(n_items))
    finally:
        c.close()
        sitl.stop()
        proxy.stop()
    return {"seed": seed, "ack": ack, "ok": ack == 0 and held, "wall_s": time.monotonic() - t0,
            "up": asdict(proxy.up.counts), "down": asdict(proxy.down.counts)}
