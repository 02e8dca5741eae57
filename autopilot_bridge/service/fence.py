"""Before take-off: the field's fence on the autopilot, verified, or no flight.

The field module gives the companion one inclusion polygon (the field) and any exclusion
polygons (a pond, a barn) as (lat, lon) lists in WGS84 degrees. Here they are checked against
home, uploaded with the MAVLink mission protocol (MAV_MISSION_TYPE_FENCE: one
MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION / _EXCLUSION item per vertex, param 1 the polygon's
vertex count, as QGroundControl and MAVProxy send them), read back and compared vertex by
vertex (to 1e-7 degrees, the wire's resolution), and enabled with the dialect's parameters
(`Dialect.fence_params`: ArduPilot's FENCE_ENABLE / FENCE_TYPE / FENCE_ACTION, PX4's
GF_ACTION). Any failure is `FenceRefused`, one line naming what failed; the companion then
does not take off.

Home's test is an exact ray cast on the vertices' 1e-7-degree integers, the very numbers the
autopilot stores (ArduPilot tests them the same way, PX4 in doubles): no projection and no
floating point can put home on the wrong side, and the companion needs no geometry library
(shapely is the field module's). A home on an edge counts as outside: the first GPS wobble
would breach.
"""

from __future__ import annotations

import logging
import math
import queue
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from ..link.connection import LinkError, VehicleLink, mavlink

log = logging.getLogger(__name__)
FENCE = mavlink.MAV_MISSION_TYPE_FENCE
INCLUSION = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
EXCLUSION = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
TOLERANCE_E7 = 1  # read-back tolerance: 1e-7 degrees
LatLon = tuple[float, float]


#: a polygon field's fence margin (m; `FencePlan.of_field`): the autopilot tests its estimate,
#: truth + the receiver's bias (0.7 m sd an axis in our SITL, 3.6 sigma at 2.5 m), while the
#: companion flies the true cell centres, which lie in the field and half a cell or more from
#: its no-fly zones
FIELD_MARGIN_M = 2.5


class FenceRefused(RuntimeError):
    """The fence could not be put on the vehicle as planned, or home lies outside it: the
    companion will not take off."""


class FenceBreached(RuntimeError):
    """The vehicle's position was seen outside the fence in flight: the companion flies it no
    further (its next leg would take the vehicle back out of the autopilot's fence action)."""


def to_e7(deg: float) -> int:
    return int(round(deg * 1e7))


def _ring(points: Sequence[Sequence[float]], what: str) -> tuple[LatLon, ...]:
    """A polygon's vertices, checked; a closing vertex equal to the first is dropped."""
    try:
        ring = [(float(p[0]), float(p[1])) for p in points]
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"{what}: vertices must be (lat, lon) pairs of numbers") from None
    for lat, lon in ring:
        if not (math.isfinite(lat) and math.isfinite(lon) and abs(lat) <= 90 and abs(lon) <= 180):
            raise ValueError(f"{what}: vertex ({lat}, {lon}) is not a WGS84 lat/lon in degrees")
    if len(ring) > 1 and (to_e7(ring[0][0]), to_e7(ring[0][1])) == (to_e7(ring[-1][0]), to_e7(ring[-1][1])):
        ring.pop()
    if len({(to_e7(a), to_e7(b)) for a, b in ring}) < 3:
        raise ValueError(f"{what}: a polygon needs at least 3 distinct vertices (got {len(ring)})")
    if len(ring) > 255:
        raise ValueError(f"{what}: {len(ring)} vertices; a fence polygon has at most 255 (ArduPilot's uint8 count)")
    return tuple(ring)


@dataclass(frozen=True)
class FencePlan:
    """The field's fence: one inclusion polygon and any exclusion polygons, (lat, lon) degrees."""

    inclusion: tuple[LatLon, ...]
    exclusions: tuple[tuple[LatLon, ...], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "inclusion", _ring(self.inclusion, "fence inclusion polygon"))
        object.__setattr__(self, "exclusions", tuple(
            _ring(r, f"fence exclusion polygon {i}") for i, r in enumerate(self.exclusions)))

    @classmethod
    def of(cls, inclusion: Sequence[Sequence[float]],
           exclusions: Sequence[Sequence[Sequence[float]]] = ()) -> FencePlan:
        """From the field module's lists: `inclusion: list[(lat, lon)]`,
        `exclusions: list[list[(lat, lon)]]`."""
        return cls(tuple(map(tuple, inclusion)), tuple(tuple(map(tuple, r)) for r in exclusions))

    @classmethod
    def of_field(cls, field, margin_m: float = 0.0) -> FencePlan:
        """A polygon field's fence: its outer ring, and each no-fly zone (holes and exclusions)
        as an exclusion polygon. Duck-typed on sim.field.PolygonField (`outer`, `no_fly[i].ring`,
        `fence_rings`) so the companion does not import the field module. margin_m: room for
        the autopilot's position estimate, the outer ring grown and the no-fly rings shrunk by
        it (`PolygonField.fence_rings`); 0, the rings as drawn."""
        if margin_m:
            outer, no_fly = field.fence_rings(margin_m)
            return cls.of(outer, no_fly)
        return cls.of(field.outer, [z.ring for z in field.no_fly])

    def items(self) -> list[tuple[int, int, int, int]]:
        """(command, vertex count, lat e7, lon e7) per item, in upload order."""
        out = []
        for cmd, ring in [(INCLUSION, self.inclusion)] + [(EXCLUSION, r) for r in self.exclusions]:
            out += [(cmd, len(ring), to_e7(lat), to_e7(lon)) for lat, lon in ring]
        return out


# -- geometry ------------------------------------------------------------------------------
def locate(point: tuple[int, int], ring: Sequence[tuple[int, int]]) -> int:
    """Where an integer point lies against an integer polygon: 1 inside, 0 on an edge or vertex,
    -1 outside. Exact: ray casting with integer cross products (Python ints do not overflow)."""
    px, py = point
    inside = False
    n = len(ring)
    for i in range(n):
        (ax, ay), (bx, by) = ring[i], ring[(i + 1) % n]
        cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
        if cross == 0 and min(ax, bx) <= px <= max(ax, bx) and min(ay, by) <= py <= max(ay, by):
            return 0
        if (ay > py) != (by > py):  # the edge spans the horizontal line through the point
            # crossing x > px  <=>  cross has the sign of (by - ay)
            if (cross > 0) == (by > ay):
                inside = not inside
    return 1 if inside else -1


def where(plan: FencePlan, lat_e7: int, lon_e7: int) -> str | None:
    """None when the point is strictly inside the fence, else what it breaches."""
    p = (lat_e7, lon_e7)
    if locate(p, [(to_e7(a), to_e7(b)) for a, b in plan.inclusion]) <= 0:
        return "outside the inclusion polygon"
    for i, ring in enumerate(plan.exclusions):
        if locate(p, [(to_e7(a), to_e7(b)) for a, b in ring]) >= 0:
            return f"inside exclusion polygon {i}"
    return None


class BreachWatch:
    """The autopilot's position estimate (GLOBAL_POSITION_INT) tested against the plan on the
    link's receive thread: the first position outside is kept. The autopilots' own reports
    differ (PX4 sets no SYS_STATUS geofence bit, ArduCopter streams SYS_STATUS only when asked),
    the estimate and the fence they test are the same everywhere."""

    def __init__(self, link: VehicleLink, plan: FencePlan) -> None:
        self.link, self.plan = link, plan
        self.outside: tuple[float, float, str] | None = None  # (lat, lon, what) first seen outside
        link.add_handler(self._on)

    def _on(self, msg) -> None:
        if self.outside is None and msg.get_type() == "GLOBAL_POSITION_INT":
            what = where(self.plan, msg.lat, msg.lon)
            if what is not None:
                self.outside = (msg.lat * 1e-7, msg.lon * 1e-7, what)

    def check(self) -> None:
        """FenceBreached, one line, once a position outside has been seen."""
        if self.outside is not None:
            lat, lon, what = self.outside
            raise FenceBreached(f"fence breached: the vehicle was at ({lat:.7f}, {lon:.7f}), {what}; the companion "
                                "flies no further legs")

    def close(self) -> None:
        self.link.remove_handler(self._on)


def home_check(plan: FencePlan, lat: float, lon: float) -> None:
    """FenceRefused unless home lies strictly inside the inclusion polygon and outside every
    exclusion polygon."""
    p = (to_e7(lat), to_e7(lon))
    where = locate(p, [(to_e7(a), to_e7(b)) for a, b in plan.inclusion])
    if where <= 0:
        raise FenceRefused(f"refusing to fly: home ({lat:.7f}, {lon:.7f}) is "
                           f"{'on the edge of' if where == 0 else 'outside'} the fence's inclusion polygon")
    for i, ring in enumerate(plan.exclusions):
        where = locate(p, [(to_e7(a), to_e7(b)) for a, b in ring])
        if where >= 0:
            raise FenceRefused(f"refusing to fly: home ({lat:.7f}, {lon:.7f}) is "
                               f"{'on the edge of' if where == 0 else 'inside'} the fence's exclusion polygon {i}")


# -- the mission protocol ------------------------------------------------------------------
class _Transfer:
    """The link's fence-type mission messages from the autopilot, queued while a transfer runs."""

    KINDS = frozenset({"MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK", "MISSION_COUNT", "MISSION_ITEM_INT",
                       "MISSION_ITEM"})

    def __init__(self, link: VehicleLink) -> None:
        self.link, self.q = link, queue.Queue()

    def __enter__(self) -> _Transfer:
        self.link.add_handler(self._on)
        return self

    def __exit__(self, *exc) -> None:
        self.link.remove_handler(self._on)

    def _on(self, msg) -> None:
        if msg.get_type() in self.KINDS and getattr(msg, "mission_type", 0) == FENCE and (
                msg.get_srcSystem(), msg.get_srcComponent()) == self.link.target:
            self.q.put(msg)

    def next(self, timeout: float):
        try:
            return self.q.get(timeout=timeout)
        except queue.Empty:
            return None


def _result_name(result: int) -> str:
    e = mavlink.enums["MAV_MISSION_RESULT"].get(result)
    return e.name if e else str(result)


def upload(link: VehicleLink, plan: FencePlan, timeout: float = 1.0, retries: int = 5) -> None:
    """MISSION_COUNT, then each item the vehicle asks for (MISSION_REQUEST_INT, or ArduPilot's
    MISSION_REQUEST), until its MISSION_ACK; the last message is resent when the vehicle stays
    silent for `timeout`. FenceRefused names the ACK's result and what the vehicle said."""
    items = plan.items()
    mav = link.conn.mav
    sys_id, comp = link.target
    count_msg = mav.mission_count_encode(sys_id, comp, len(items), FENCE)
    last, silent, t0 = count_msg, 0, time.monotonic()
    with _Transfer(link) as tr:
        link.send_message(count_msg)
        while True:
            m = tr.next(timeout)
            if m is None:
                silent += 1
                if silent > retries:
                    raise FenceRefused(f"refusing to fly: fence upload: the vehicle stopped answering "
                                       f"({retries} resends of {last.get_type()})")
                link.send_message(last)
                continue
            kind = m.get_type()
            if kind == "MISSION_ACK":
                if m.type == mavlink.MAV_MISSION_ACCEPTED:
                    return
                said = link._reason_since(t0)  # noqa: SLF001 - the STATUSTEXTs said alongside
                raise FenceRefused(f"refusing to fly: fence upload refused: MISSION_ACK {_result_name(m.type)}"
                                   + (f" ({said})" if said else ""))
            if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                if not 0 <= m.seq < len(items):
                    raise FenceRefused(f"refusing to fly: fence upload: the vehicle asked for item {m.seq} of "
                                       f"{len(items)}")
                cmd, n, x, y = items[m.seq]
                last = mav.mission_item_int_encode(sys_id, comp, m.seq, mavlink.MAV_FRAME_GLOBAL, cmd, 0, 0, float(n),
                                                   0, 0, 0, x, y, 0.0, FENCE)
                link.send_message(last)
                silent = 0


def download(link: VehicleLink, timeout: float = 1.0, retries: int = 5) -> list[tuple[int, int, int, int]]:
    """The vehicle's fence items as (command, param 1 rounded, lat e7, lon e7)."""
    mav = link.conn.mav
    sys_id, comp = link.target
    with _Transfer(link) as tr:
        def ask(msg, want: str, seq: int | None = None):
            for _ in range(retries + 1):
                link.send_message(msg)
                end = time.monotonic() + timeout
                while (left := end - time.monotonic()) > 0:
                    m = tr.next(left)
                    if m is None:
                        break
                    if m.get_type() == "MISSION_ACK" and m.type != mavlink.MAV_MISSION_ACCEPTED:
                        raise FenceRefused(f"refusing to fly: fence read-back refused: MISSION_ACK "
                                           f"{_result_name(m.type)}")
                    if m.get_type() == want and (seq is None or m.seq == seq):
                        return m
            raise FenceRefused(f"refusing to fly: fence read-back: no {want}"
                               + ("" if seq is None else f" for item {seq}") + f" after {retries + 1} tries")

        n = ask(mav.mission_request_list_encode(sys_id, comp, FENCE), "MISSION_COUNT").count
        out = []
        for seq in range(n):
            m = ask(mav.mission_request_int_encode(sys_id, comp, seq, FENCE), "MISSION_ITEM_INT", seq)
            out.append((m.command, int(round(m.param1)), m.x, m.y))
        link.send_message(mav.mission_ack_encode(sys_id, comp, mavlink.MAV_MISSION_ACCEPTED, FENCE))
    return out


def verify(plan: FencePlan, got: list[tuple[int, int, int, int]]) -> None:
    """FenceRefused naming the first item the vehicle holds otherwise than planned."""
    want = plan.items()
    if len(got) != len(want):
        raise FenceRefused(f"refusing to fly: fence read-back: the vehicle holds {len(got)} items, "
                           f"{len(want)} were uploaded")
    for seq, (w, g) in enumerate(zip(want, got, strict=True)):
        if w[:2] != g[:2] or abs(w[2] - g[2]) > TOLERANCE_E7 or abs(w[3] - g[3]) > TOLERANCE_E7:
            raise FenceRefused(f"refusing to fly: fence read-back: item {seq} is command {g[0]}, {g[1]} vertices at "
                               f"({g[2] * 1e-7:.7f}, {g[3] * 1e-7:.7f}); uploaded command {w[0]}, {w[1]} vertices at "
                               f"({w[2] * 1e-7:.7f}, {w[3] * 1e-7:.7f})")


def enable(link: VehicleLink, echo: Callable[[str], None] = log.info) -> list[str]:
    """Set the dialect's fence parameters that are not yet right (each PARAM_SET read back);
    returns what was changed, one line each."""
    changed = []
    for p in link.require_dialect().fence_params():
        value = link.get_param(p.name)
        if value is None:
            raise FenceRefused(f"refusing to fly: the vehicle has no parameter {p.name} ({p.why})")
        if p.ok(value):
            continue
        want = p.fix(value)
        try:
            got = link.set_param(p.name, want)
        except LinkError as e:
            raise FenceRefused(f"refusing to fly: setting {p.name} = {want:g} failed: {e}") from e
        if not p.ok(got):
            raise FenceRefused(f"refusing to fly: the vehicle kept {p.name} = {got:g} after PARAM_SET {want:g} "
                               f"({p.why})")
        line = f"fence: {p.name} {value:g} -> {got:g} ({p.why})"
        echo(line)
        changed.append(line)
    return changed


def ensure_fence(link: VehicleLink, plan: FencePlan, echo: Callable[[str], None] = log.info,
                 home_timeout: float = 10.0) -> list[str]:
    """The pre-flight fence: home inside the plan, uploaded, read back equal, enabled. Returns
    the preflight log's lines; FenceRefused (one line) when any step fails."""
    link.wait_for(lambda: bool(link.telemetry.home), home_timeout, "a home position (the fence is checked against it)")
    home = link.telemetry.home
    home_check(plan, home["lat"], home["lon"])
    upload(link, plan)
    verify(plan, download(link))
    lines = [f"fence: {len(plan.items())} vertices uploaded and read back (1 inclusion, "
             f"{len(plan.exclusions)} exclusion polygons); home inside"]
    echo(lines[0])
    return lines + enable(link, echo)
