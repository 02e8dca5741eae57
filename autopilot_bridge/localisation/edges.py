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
