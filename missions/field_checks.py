"""The scorer's checks of a flight over a real field: did anything leave the field or enter a
no-fly zone? Read from the vehicle's own record (its tlog: every setpoint it heard, every
position estimate it sent) and from the simulator's truth, never from the companion's word.

- `setpoints`, `setpoints_outside_fence`: the SET_POSITION_TARGET_LOCAL_NED positions the
  vehicle received, and how many lie outside the fence the companion uploaded (the autopilot's
  own test, in its estimate's frame: `autopilot_bridge.service.fence.where`, integer 1e-7 degrees);
  `setpoints_outside_rings`, the same against the field's rings as drawn (information: in the
  estimate's frame a border cell's setpoint lies past the ring by the bias it is shifted by).
- `setpoints_off_field`: how many of those positions, less the GPS bias the companion had
  registered (they are shifted by it so the camera is truly over the cell), lie outside the
  field's outer ring or in a no-fly zone: where each setpoint sends the vehicle truly, on the
  field's own rings. Taken from the companion's log (`SearchLog.setpoint_field_ne`).
- `breaches`: GLOBAL_POSITION_INT estimates the vehicle sent outside the fence (what the
  companion's BreachWatch and an autopilot's fence test), and `fence_rejections`, the
  vehicle's own count of setpoints it refused and fence holds.
- `true_off_field`: simulator ticks at which the vehicle truly was off the field or over a
  no-fly zone (its true position, any height), how far past the ring it reached at most
  (`true_off_field_max_m`) and where (`true_off_field_where`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def _tlog_messages(path: Path, kinds: set[str]) -> list[Any]:
    from pymavlink import mavutil

    # the default dialect (ardupilotmega, a superset of common): `dialect=` would call
    # mavutil.set_dialect, which changes every later connection of this process (a test's
    # ground station then no longer decodes ArduPilot's EKF_STATUS_REPORT)
    conn = mavutil.mavlink_connection(str(path))
    out = []
    try:
        while True:
            m = conn.recv_match(type=list(kinds))
            if m is None:
                break
            out.append(m)
    finally:
        conn.close()
    return out


def field_checks(field, fence, tlog: Path, spawn_ne: np.ndarray, truth: np.ndarray, counters: Any,
                 setpoint_field_ne: list | None = None) -> dict[str, Any]:
    """The checks above for one flight. field: `sim.field.PolygonField`; fence: the uploaded
    `FencePlan`; tlog: the SITL's; spawn_ne: home in the field's NED (the vehicle's local origin);
    truth: (T, 3) simulated s, true north, east about cell (0, 0); counters: the vehicle's."""
    from autopilot_bridge.service.fence import to_e7, where

    msgs = _tlog_messages(Path(tlog), {"SET_POSITION_TARGET_LOCAL_NED", "GLOBAL_POSITION_INT"})
    proj = field.projection
    sp = np.array([[m.x, m.y] for m in msgs if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"
                   and not m.type_mask & 1], dtype=float).reshape(-1, 2)
    sp_ne = sp + np.asarray(spawn_ne, dtype=float)[:2]
    # the same positions against the rings as drawn: in the autopilot's estimate frame, so a
    # setpoint for a border cell lies past the ring by the GPS bias it is shifted by (information)
    outside_rings = int((~field.allowed(sp_ne)).sum()) if len(sp_ne) else 0
    outside_fence = sum(where(fence, to_e7(lat), to_e7(lon)) is not None for lat, lon in proj.to_latlon(sp_ne)) \
        if len(sp_ne) else 0
    est = [(m.lat, m.lon) for m in msgs if m.get_type() == "GLOBAL_POSITION_INT"]
    breaches = sum(where(fence, lat, lon) is not None for lat, lon in est)
    meant = np.asarray(setpoint_field_ne if setpoint_field_ne is not None else [], dtype=float).reshape(-1, 2)
    off_field = int((~field.allowed(meant)).sum()) if len(meant) else 0
    off = ~field.allowed(truth[:, 1:3]) if len(truth) else np.zeros(0, bool)
    true_off = int(off.sum())
    depth, where_off = _how_far_off(field, truth[off, 1:3]) if true_off else (0.0, [])
    return {"setpoints": int(len(sp)), "setpoints_outside_fence": int(outside_fence),
            "setpoints_outside_rings": outside_rings,
            "setpoints_meant": int(len(meant)), "setpoints_off_field": off_field,
            "estimates": len(est), "breaches": int(breaches),
            "fence_rejections": int(counters.fence_rejections), "true_ticks": int(len(truth)),
            "true_off_field": true_off, "true_off_field_max_m": round(depth, 3), "true_off_field_where": where_off,
            "fence_margin_m": None}


def _how_far_off(field, ne: np.ndarray) -> tuple[float, list[str]]:
    """How far (m) the true positions off the field reach past its rings at most, and where:
    outside the outer ring, or into which no-fly zone (by name or index)."""
    import shapely

    outer, rings = field.rings_ne()
    pts = shapely.points(ne[:, 1], ne[:, 0])
    ring = shapely.Polygon(outer[:, ::-1])
    out = ~shapely.intersects(ring, pts)
    depth = float(shapely.distance(ring, pts[out]).max()) if out.any() else 0.0
    where = ["outside the outer ring"] if out.any() else []
    for i, (z, r) in enumerate(zip(field.no_fly, rings, strict=True)):
        poly = shapely.Polygon(r[:, ::-1])
        inside = shapely.contains(poly, pts)
        if inside.any():
            depth = max(depth, float(shapely.distance(poly.exterior, pts[inside]).max()))
            where.append(f"in no-fly zone {z.name or i} ({z.kind})")
    return depth, where
