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
    from autopilot_bridge.link import VehicleLink
    from autopilot_bridge.service import PolicyService, SearchSpec
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
                            SearchSpec(origin=sitl.field_origin, grid=grid, max_moves=max_moves), seed=seed)
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
