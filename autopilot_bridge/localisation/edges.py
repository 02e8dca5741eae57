"""The field's edge in a camera frame: where the grass ends, as a GPS-free position measurement.

A paddock is fenced, with a track or stubble beside the fence (`sim.vehicle.field.EDGE`). From
within two cells of the border the downward camera sees the line where the grass ends, and its
offset from the nadir says where the camera truly is along that axis, with no lattice ambiguity:
a target only says "a whole number of cells from here", the edge says "here". Between finds the
receiver's bias drifts (flight seed 40: 1.4-2 m east in 14 decisions with no cow in view) and the
next cow then registers the frame a cell off; each pass along the border pins it back.

The frame is north-up (the gimbal keeps it aligned to the grid), so each border is a row or a
column of the frame: per side, every pixel line across it is read from the frame's edge inwards
(how many of its pixels are track), and the lines that agree give the border's position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the track round the field as the camera sees it (sim.vehicle.field.EDGE, rendered): the
#: colour a survey of the paddock's edge would calibrate
EDGE_RGB = (176.0, 157.0, 109.0)
#: a pixel within this RGB distance of EDGE_RGB is track (rendered flat; the nearest coat pixel,
#: a white cow's shaded side, is 41 away)
EDGE_DISTANCE = 20.0
#: pixel lines across a border that must show it (a run of track from the frame's edge)
MIN_LINES = 6
#: and the share of them within a pixel of their median (a cow at the border shortens the lines
#: it covers)
AGREE = 0.6
#: where the renderer samples a pixel: the borders read at the pixel lines' centres showed
#: 0.5 px (0.085 m) north-east of the truth on every side (581 rendered sightings), so each
#: border is taken half a pixel south-west of its run's end
SHIFT_PX = 0.5
#: a line's run of track must end on grass (within this RGB distance of the frame's grass): one
#: that ends on a cow says where the cow is (a cow at the border is seen over the track, its
#: back magnified outwards: its straight side made a border 3.9 m off)
GRASS_DISTANCE = 70.0


@dataclass(frozen=True)
class EdgeSighting:
    """One border of the field seen in a frame."""

    axis: int  # 0: a north or south border (a row of the frame), 1: east or west (a column)
    side: int  # +1: the north (east) border, -1: the south (west) border
    #: the border's offset from the camera's nadir along the axis (north or east metres)
    offset_m: float
    lines: int  # the pixel lines that agree on it


def edge_mask(frame: np.ndarray, rgb: tuple[float, float, float] = EDGE_RGB,
              distance: float = EDGE_DISTANCE) -> np.ndarray:
    """(H, W, 3) -> (H, W) bool: the pixels that are the track round the field."""
    f = np.asarray(frame, dtype=np.float32)
    return np.linalg.norm(f - np.asarray(rgb, np.float32), axis=-1) < distance


def half_footprint_m(camera_height_m: float, fov_deg: float = 100.0) -> float:
    """Half the ground the frame spans along an axis (m), the camera this high above it."""
    return camera_height_m * math.tan(math.radians(fov_deg / 2))


def ground_px_per_m(camera_height_m: float, width_px: int = 50, fov_deg: float = 100.0) -> float:
    """Pixels per metre on the ground (pinhole, nadir) with the camera this high above it."""
    return (width_px / 2) / half_footprint_m(max(camera_height_m, 0.1), fov_deg)


def _runs(mask: np.ndarray, grass: np.ndarray) -> np.ndarray:
    """Per row: how many pixels from the row's start (column 0) on are True, unbroken; 0 where
    the run ends on a pixel that is not grass (occluded: it says nothing of the border)."""
    off = ~mask
    runs = np.where(off.any(axis=1), off.argmax(axis=1), mask.shape[1])
    end = np.minimum(runs, mask.shape[1] - 1)
    return np.where((runs < mask.shape[1]) & ~grass[np.arange(len(runs)), end], 0, runs)


def find_edges(frame: np.ndarray, camera_height_m: float, fov_deg: float = 100.0) -> list[EdgeSighting]:
    """The field's borders seen in a north-up frame, each with its offset from the nadir.

    Per side (north, south, west, east), each pixel line across it is read from the frame's
    edge: its run of track pixels ends where the grass begins. Lines all track (beyond the
    other axis' border) and lines with none say nothing; a side is seen when at least MIN_LINES
    lines show a run and AGREE of them end within a pixel of their median. A pixel is track when
    its centre is beyond the border, so the border lies between the run's last pixel centre and
    the next one's: at the run's length, in pixels from the frame's edge (to half a pixel)."""
    h, w = frame.shape[:2]
    m = edge_mask(frame)
    if not m.any() or m.all():
        return []
    f = np.asarray(frame, dtype=np.float32)
    grass = np.linalg.norm(f - np.median(f[~m], axis=0), axis=-1) < GRASS_DISTANCE
    k = ground_px_per_m(camera_height_m, w, fov_deg)
    out = []
    # (axis, side, the masks with the side's frame edge first, lines' length, offset from a run)
    sides = (
        (0, +1, m.T, grass.T, h, lambda r: (h / 2 - r - SHIFT_PX) / k),  # north: rows from the top
        (0, -1, m.T[:, ::-1], grass.T[:, ::-1], h, lambda r: (r - h / 2 - SHIFT_PX) / k),  # south
        (1, -1, m, grass, w, lambda r: (r - w / 2 - SHIFT_PX) / k),  # west: columns from the left
        (1, +1, m[:, ::-1], grass[:, ::-1], w, lambda r: (w / 2 - r - SHIFT_PX) / k),  # east
    )
    for axis, side, lines_first, grass_first, length, offset in sides:
        runs = _runs(lines_first, grass_first)
        shown = runs[(runs > 0) & (runs < length)]
        if len(shown) < MIN_LINES:
            continue
        med = float(np.median(shown))
        agree = shown[np.abs(shown - med) <= 1]
        if len(agree) < AGREE * len(shown) or len(agree) < MIN_LINES:
            continue
        out.append(EdgeSighting(axis, side, float(offset(float(np.mean(agree)))), int(len(agree))))
    return out


def border_ne(axis: int, side: int, width: int, height: int, cell_m: float = 2.0) -> float:
    """Where a border of a width x height field lies along its axis (north or east metres; cell
    (x, y) is at north -y * cell_m, east x * cell_m, the border half a cell beyond the outer cells)."""
    if axis == 0:
        return 0.5 * cell_m if side > 0 else -(height - 0.5) * cell_m
    return (width - 0.5) * cell_m if side > 0 else -0.5 * cell_m


# -- a polygon field's edges at any angle --------------------------------------------------------
#
# A real field's edges run at any angle to the grid (the farm: one of five along a grid axis),
# and the rows-and-columns reading above sees only those along an axis: the GPS bias then went
# uncorrected for 40 decisions along the farm's slanted sides (flight seed 9: the vehicle truly
# 1.28 m past the ring). The frame is held to the grid, so each polygon edge's direction in it
# is known: what the frame tells is where that line lies across itself, one number. Every track
# or grass pixel near the edge (nearer to it than to any other edge of the ring) is a vote: track
# beyond the line, grass inside it; the line is put where the votes disagree least.

#: pixels of each kind (track, grass) a polygon edge's fit must have
MIN_PIXELS = 25
#: the share of the fit's pixels on the wrong side of its line it may leave (a cow's pixels are
#: neither kind and left out; a mis-matched edge or one at another angle leaves many)
MAX_WRONG = 0.04
#: pixels whose ground point lies this close (m) to an end of the edge are left out (a corner:
#: the next edge's track) ...
CORNER_M = 0.6
#: ... and the line sought lies within this many metres of where the believed position puts it
SEARCH_M = 2.5


@dataclass(frozen=True)
class RingEdgeSighting:
    """One edge of a polygon field's outer ring seen in a frame, at any angle to the grid."""

    edge: int  # which edge of the ring (from vertex edge to vertex edge + 1)
    #: the edge's unit normal out of the field (grid frame: ahead, right)
    normal_ne: tuple[float, float]
    #: the edge's offset from the camera's nadir along the normal (m; > 0 the edge lies outwards)
    offset_m: float
    pixels: int  # the pixels the line was fitted to


def ring_normals(ring: np.ndarray) -> np.ndarray:
    """(n, 2) ring (grid frame, not closed) -> (n, 2) each edge's unit normal out of the field."""
    ring = np.asarray(ring, dtype=float)
    d = np.roll(ring, -1, axis=0) - ring
    length = np.linalg.norm(d, axis=1, keepdims=True)
    if np.any(length < 1e-9):
        raise ValueError("a ring's edges must have a length (two vertices coincide)")
    t = d / length
    # the shoelace area with (north, east) as (x, y): > 0 when the ring runs clockwise seen from
    # above (the swap of axes mirrors the map), the field then on the right of each edge
    x, y = ring[:, 0], ring[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    right = np.stack([-t[:, 1], t[:, 0]], axis=1)  # right of travel (north -> east)
    return -right if area > 0 else right


def _pixel_ground_ne(h: int, w: int, camera_height_m: float, fov_deg: float) -> np.ndarray:
    """(h, w, 2): where each pixel samples the ground, (ahead, right) metres from the nadir: its
    centre moved SHIFT_PX back and left, as the rows-and-columns reading measured it (borders
    read at the pixels' centres lay half a pixel ahead and right of the truth on every side;
    rendered slanted edges read so: 0.005 m mean error)."""
    k = ground_px_per_m(camera_height_m, w, fov_deg)
    north = (h / 2 - np.arange(h) - 0.5 - SHIFT_PX) / k
    east = (np.arange(w) + 0.5 - SHIFT_PX - w / 2) / k
    return np.stack(np.broadcast_arrays(north[:, None], east[None, :]), axis=-1)


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 2) points -> (...) their distance to segment a-b."""
    d = b - a
    u = np.clip(((points - a) @ d) / float(d @ d), 0.0, 1.0)
    return np.linalg.norm(points - (a + u[..., None] * d), axis=-1)


def _split(s: np.ndarray, track: np.ndarray) -> tuple[float, int]:
    """1-D: track beyond the line, grass inside it; s the pixels' places across the line.
    Returns the line's place (midway between the two pixels it falls between, the middle of
    the best places when several tie) and how many pixels are on the wrong side of it."""
    order = np.argsort(s, kind="stable")
    s, y = s[order], track[order]
    # the line before sorted pixel i: the track pixels before it and the grass from it on are wrong
    wrong = np.concatenate([[0], np.cumsum(y)]) + np.concatenate([np.cumsum((~y)[::-1])[::-1], [0]])
    best = np.flatnonzero(wrong == wrong.min())
    i = int(best[len(best) // 2])
    if i == 0:
        return float(s[0]), int(wrong[i])
    if i == len(s):
        return float(s[-1]), int(wrong[i])
    return float((s[i - 1] + s[i]) / 2), int(wrong[i])


def find_ring_edges(frame: np.ndarray, camera_height_m: float, ring: np.ndarray, camera_ne: np.ndarray,
                    fov_deg: float = 100.0) -> list[RingEdgeSighting]:
    """The edges of a polygon field's outer ring (grid frame, metres) seen in a frame held to the
    grid, the camera believed at camera_ne: per edge, the track and grass pixels whose ground
    point (at the believed position) lies nearer that edge than any other, away from its ends
    (CORNER_M), and within SEARCH_M of it; the line along the edge's direction that splits them
    with the fewest on the wrong side. Seen when there are MIN_PIXELS of each kind and at most
    MAX_WRONG of them are wrong: a line at another angle, or some other boundary, leaves more."""
    h, w = frame.shape[:2]
    m = edge_mask(frame)
    if not m.any() or m.all():
        return []
    ring = np.asarray(ring, dtype=float)
    f = np.asarray(frame, dtype=np.float32)
    grass = ~m & (np.linalg.norm(f - np.median(f[~m], axis=0), axis=-1) < GRASS_DISTANCE)
    p = _pixel_ground_ne(h, w, camera_height_m, fov_deg)
    use = m | grass
    p, track = p[use], m[use]
    g = p + np.asarray(camera_ne, dtype=float)[:2]
    ends = np.roll(ring, -1, axis=0)
    dist = np.stack([_segment_distance(g, a, b) for a, b in zip(ring, ends, strict=True)])  # (edges, pixels)
    nearest = np.argmin(dist, axis=0)
    normals = ring_normals(ring)
    out = []
    for i, (a, b) in enumerate(zip(ring, ends, strict=True)):
        n = normals[i]
        t = (b - a) / np.linalg.norm(b - a)
        along = (g - a) @ t
        sel = (nearest == i) & (dist[i] < SEARCH_M) & (along > CORNER_M) & (along < float(np.linalg.norm(b - a)) - CORNER_M)
        n_track = int(track[sel].sum())
        if n_track < MIN_PIXELS or int(sel.sum()) - n_track < MIN_PIXELS:
            continue
        s = p[sel] @ n  # across the edge, from the nadir (outwards)
        d, wrong = _split(s, track[sel])
        if wrong > MAX_WRONG * int(sel.sum()):
            continue
        out.append(RingEdgeSighting(i, (float(n[0]), float(n[1])), d, int(sel.sum())))
    return out
