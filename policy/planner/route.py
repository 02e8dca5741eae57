"""The route of a static search with altitude levels: where to look from above and which
sighted targets to recover, as one open tour over (cell, level) stops (issue 27).

Why a route: the (cell, level) rule (policy.planner.altitude) weighs each goal by what it
brings per move, one goal at a time; it cannot see that a sighted target beside the part of
the field still to be surveyed costs a few moves later and a descent and a climb (4 moves at
level 3) now. Here the rest of the search is one tour, re-planned as the belief changes:

- Looks: the field is cut into tiles of at most the top level's footprint (7 x 7 at level 3).
  A tile with cells still worth looking at (never-sighted mass) is one stop: the centre of
  the box around those cells, at the lowest level whose footprint covers the box (a few
  leftover cells near a pickup are looked at from level 1 on the way, with no climb).
- Pickups: each cell believed occupied is a stop at level 1.
- A leg costs its moves: |dx| + |dy| + |level change|. The open tour from the agent through
  every stop (cheapest insertion, warm-started from the last decision's order, then 2-opt
  and single-stop moves) puts a pickup where it is cheapest: now, with its neighbours in one
  descent, or later when the survey passes by again, or in the close-up tour at the end.

The first stop of the tour is the goal; the altitude rule's moves take the agent there (climb
first, travel, descend on arrival). Everything per episode is a handful of small numpy
arrays (at most tiles + targets stops, 9 + 10 on 20 x 20).
"""

from __future__ import annotations

import numpy as np


def tile_edges(cells: int, size: int) -> np.ndarray:
    """Edges of the fewest tiles of at most `size` cells along an axis of `cells`, as even
    as they come (20 cells, size 7: 0, 7, 13, 20)."""
    k = -(-cells // size)
    return np.round(np.linspace(0, cells, k + 1)).astype(np.int64)


def look_stops(need: np.ndarray, ex: np.ndarray, ey: np.ndarray, top: int) -> tuple[np.ndarray, np.ndarray]:
    """need (n, h, w) bool: cells still worth looking at. Returns stops (n, T, 3) (x, y, level)
    and live (n, T) bool, one per tile (T = tiles), row-major: the centre of the box around
    the tile's needy cells, at the lowest level (<= top) whose footprint covers it."""
    n = need.shape[0]
    ys = np.arange(need.shape[1])
    xs = np.arange(need.shape[2])
    stops, live = [], []
    for y0, y1 in zip(ey[:-1], ey[1:], strict=True):
        rows_any = need[:, y0:y1, :]  # (n, th, w)
        for x0, x1 in zip(ex[:-1], ex[1:], strict=True):
            t = rows_any[:, :, x0:x1]
            ay = t.any(axis=2)  # (n, th)
            ax = t.any(axis=1)  # (n, tw)
            ok = ay.any(axis=1)
            yy, xx = ys[y0:y1], xs[x0:x1]
            lo_y = np.where(ay, yy[None], 1 << 30).min(axis=1)
            hi_y = np.where(ay, yy[None], -1).max(axis=1)
            lo_x = np.where(ax, xx[None], 1 << 30).min(axis=1)
            hi_x = np.where(ax, xx[None], -1).max(axis=1)
            cx, cy = (lo_x + hi_x) // 2, (lo_y + hi_y) // 2
            r = np.maximum(hi_x - cx, hi_y - cy)  # the footprint radius that covers the box
            lv = np.clip(r, 1, top)
            stops.append(np.stack([cx, cy, lv], axis=1))
            live.append(ok)
    if not stops:
        return np.zeros((n, 0, 3), np.int64), np.zeros((n, 0), bool)
    return np.stack(stops, axis=1), np.stack(live, axis=1)


def leg_costs(pts: np.ndarray, climb: float = 1.0) -> np.ndarray:
    """(k, k) moves between (x, y, level) stops: |dx| + |dy| + climb * |level change|."""
    d = np.abs(pts[:, None, :] - pts[None, :, :]).astype(np.float64)
    return d[..., 0] + d[..., 1] + climb * d[..., 2]


def open_tour(cost: np.ndarray, warm: list[int] | None = None, passes: int = 30, keep: float = 0.0) -> list[int]:
    """An open tour from stop 0 through every other stop of `cost` (k, k): `warm`'s order
    (stops of it that still exist, in order) extended by cheapest insertion, then improved by
    2-opt (reversing a stretch) and or-opt (moving one stop) until neither helps. Returns the
    stops after 0, in order. keep: the warm order (extended) stays unless the improved one is
    at least this much shorter (hysteresis: the stops move a little as cells are seen, and a
    tour that flips between two near-equal orders walks back and forth)."""
    k = cost.shape[0]
    if k <= 1:
        return []
    # a dummy end stop, 0 from everywhere: the tour is open
    d = np.zeros((k + 1, k + 1))
    d[:k, :k] = cost
    end = k
    path = [0] + [s for s in (warm or []) if 0 < s < k] + [end]
    placed = np.zeros(k + 1, bool)
    placed[path] = True
    rest = [s for s in range(1, k) if not placed[s]]
    while rest:
        p = np.array(path)
        a, b = p[:-1], p[1:]
        r = np.array(rest)
        inc = d[a[None, :], r[:, None]] + d[r[:, None], b[None, :]] - d[a, b][None, :]  # (R, slots)
        i, j = np.unravel_index(int(inc.argmin()), inc.shape)
        path.insert(j + 1, int(r[i]))
        rest.pop(i)
    p = np.array(path)
    base = p.copy()
    m = len(p) - 2  # stops between start and end
    if m >= 2:
        for _ in range(passes):
            improved = False
            # 2-opt: reverse p[i..j], 1 <= i < j <= m
            prev, nxt = p[:-2], p[2:]  # prev[i - 1] = p[i - 1], nxt[j - 1] = p[j + 1]
            mid = p[1:-1]
            delta = (d[prev[:, None], mid[None, :]] + d[mid[:, None], nxt[None, :]]
                     - d[prev, mid][:, None] - d[mid, nxt][None, :])
            delta = np.triu(delta, 1) + np.tril(np.full_like(delta, np.inf))
            i, j = np.unravel_index(int(delta.argmin()), delta.shape)
            if delta[i, j] < -1e-9:
                p[i + 1: j + 2] = p[i + 1: j + 2][::-1].copy()
                improved = True
            # or-opt: move the stop at position s to between positions t and t + 1
            mid = p[1:-1]
            gain = d[p[:-2], mid] + d[mid, p[2:]] - d[p[:-2], p[2:]]  # what taking each out saves
            a, b = p[:-1], p[1:]
            ins = d[a[None, :], mid[:, None]] + d[mid[:, None], b[None, :]] - d[a, b][None, :]
            s_idx = np.arange(1, m + 1)
            t_idx = np.arange(len(a))
            adjacent = (t_idx[None, :] == s_idx[:, None]) | (t_idx[None, :] == s_idx[:, None] - 1)
            ins[adjacent] = np.inf
            delta2 = ins - gain[:, None]
            s, t = np.unravel_index(int(delta2.argmin()), delta2.shape)
            if delta2[s, t] < -1e-9:
                lst = p.tolist()
                node = lst.pop(s + 1)
                lst.insert(t + 1 if t < s + 1 else t, node)
                p = np.array(lst)
                improved = True
            if not improved:
                break
    if keep > 0 and warm and d[base[:-1], base[1:]].sum() - d[p[:-1], p[1:]].sum() < keep:
        p = base
    return [int(s) for s in p[1:-1]]


def tour_cost(cost: np.ndarray, order: list[int]) -> float:
    """Moves of the open tour 0 -> order."""
    p = [0] + order
    return float(sum(cost[a, b] for a, b in zip(p[:-1], p[1:], strict=False)))
