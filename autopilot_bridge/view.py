"""From the detector's blobs to the policy's 3 x 3 view I (target, off-map, agent channels): each
target lights the one cell its centre falls in with the camera where the posterior says, found
targets where they were found, a new one beside the camera in the slot it lies towards, and a
target two cells out, whose near end shows at the frame's edge, as a likelihood over cells.
Split from the detector (which finds the blobs in a frame) so each module holds one concern.
"""

from __future__ import annotations

import math

import numpy as np

from sim.gridworld import LEVEL_ACTIONS, Action, GridConfig, valid_mask

from .detector import Blob, px_per_m


def blob_cells(blobs: list[Blob], camera_ne: np.ndarray, camera_height_m: float,
               cell_m: float = 2.0) -> list[tuple[int, int]]:
    """The cell (x, y) each blob's target stands in, with the camera believed at camera_ne
    (field NED, metres) and camera_height_m over the ground: the cell its centre falls in."""
    out = []
    for b in blobs:
        dn, de = b.offset_ne(camera_height_m)
        n, e = camera_ne[0] + dn, camera_ne[1] + de
        out.append((int(np.floor(e / cell_m + 0.5)), int(np.floor(-n / cell_m + 0.5))))
    return out


def blobs_to_view(blobs: list[Blob], camera_ne: np.ndarray, camera_height_m: float, cell: np.ndarray,
                  width: int, height: int, radius: int = 1) -> np.ndarray:
    """The (3, W, W) uint8 view {target, off-map, agent} around `cell`, W = 2 radius + 1, from the
    blobs' cells (each target lights exactly one slot; targets outside the window, and edge blobs
    of targets beyond it (`Blob.beyond_view` for this radius), are not shown). radius 1 is the
    paper's 3 x 3 view; an altitude level l sees radius l (`level_view` lays it in the levels'
    window)."""
    if radius < 1:
        raise ValueError(f"radius must be >= 1 cell (got {radius})")
    k = 2 * radius + 1
    dy, dx = np.meshgrid(np.arange(-radius, radius + 1), np.arange(-radius, radius + 1), indexing="ij")
    ys, xs = cell[1] + dy, cell[0] + dx
    inside = (ys >= 0) & (ys < height) & (xs >= 0) & (xs < width)
    view = np.zeros((3, k, k), dtype=np.uint8)
    near = [b for b in blobs if not b.beyond_view(camera_height_m, radius)]
    show_cells(view, blob_cells(near, camera_ne, camera_height_m), cell, width, height)
    view[1] = ~inside
    view[2, radius, radius] = 1
    return view


def level_view(view: np.ndarray, level: int, levels: int, cell: np.ndarray, width: int, height: int) -> np.ndarray:
    """The (3, 2l + 1, 2l + 1) view of level l (`blobs_to_view` with radius l) laid in the
    (4, W, W) window the grid world gives a policy with altitude levels, W = 2 levels + 1:
    channels (detection, off-map, agent, outside this level's footprint), as
    sim.gridworld.BatchGridWorld._sampled_views builds them (tested against it)."""
    r, rmax = int(level), int(levels)
    if not 1 <= r <= rmax or view.shape != (3, 2 * r + 1, 2 * r + 1):
        raise ValueError(f"a level {level} view of {levels} levels must be (3, {2 * r + 1}, {2 * r + 1}) "
                         f"(got {view.shape})")
    w = 2 * rmax + 1
    off = np.arange(-rmax, rmax + 1)
    ys, xs = cell[1] + off[:, None], cell[0] + off[None, :]
    inside = (ys >= 0) & (ys < height) & (xs >= 0) & (xs < width)
    ring = np.maximum(np.abs(off)[:, None], np.abs(off)[None, :])
    out = np.zeros((4, w, w), dtype=np.uint8)
    lo = rmax - r
    out[0, lo:lo + 2 * r + 1, lo:lo + 2 * r + 1] = view[0]
    out[0] &= inside
    out[1] = ~inside
    out[2, rmax, rmax] = 1
    out[3] = inside & (ring > r)
    return out


#: a target whose near end shows at the frame's edge (`Blob.beyond_view`) has its centre this
#: far beyond that near end (m, in px_per_m's units), with this sd: rendered cows one and two
#: cells out, the camera 3.5 m up and 0-1.5 m off its cell, any heading: 1.13 and 1.24 m mean,
#: sd 0.15 and 0.17
FAR_REACH_M, FAR_REACH_SD_M = 1.2, 0.2


def far_likelihood(blob: Blob, camera_ne: np.ndarray, cov_ne: np.ndarray, cell: np.ndarray,
                   camera_height_m: float, width: int, height: int, cell_m: float = 2.0) -> np.ndarray:
    """(height, width) likelihood over the field's cells of the target whose near end `blob`
    shows at the frame's edge, the camera believed at camera_ne (field north, east) with
    covariance cov_ne, commanded over `cell`.

    Along an axis the frame cuts it, the target is one or two cells out: one cell out puts the
    camera (its true offset from the cell's centre towards the target) at cell_m - FAR_REACH_M -
    near end, two cells out a cell further, and the posterior weighs the two. Along the other
    axis its centre is read as any blob's, spread over the cells by the posterior and the
    detector's sd. Zero off the field. Why not one cell or the other: the near end alone cannot
    tell a cow a cell away with the camera a metre off its cell from one two cells away
    (`beyond_view` drops both; showing either as the neighbour at >= 30 % sent flight seed 25
    to the move cap)."""
    k = px_per_m(camera_height_m, blob.width_px)
    near = blob.inner_px / k
    offset = blob.offset_ne(camera_height_m)
    centre = np.array([-cell_m * float(cell[1]), cell_m * float(cell[0])])
    rel = np.asarray(camera_ne, dtype=float) - centre
    per_axis: list[dict[int, float]] = []  # per axis (north, east): cell index -> weight
    for i, sign in enumerate(blob.cut_sides):
        var = float(cov_ne[i][i])
        index = int(cell[1]) if i == 0 else int(cell[0])
        step = -sign if i == 0 else sign  # north is -y
        if sign:  # cut on one side along this axis: one or two cells out
            m = sign * rel[i]
            s2 = var + FAR_REACH_SD_M**2
            per_axis.append({index + step * n: math.exp(-(n * cell_m - FAR_REACH_M - near - m) ** 2 / (2 * s2))
                             for n in (1, 2)})
        else:  # read as any blob's centre, spread over the cells it may fall in
            q = float(camera_ne[i]) + offset[i]
            pos = -q / cell_m if i == 0 else q / cell_m  # in cell units along the index
            sd = math.sqrt(var + blob.sd_m**2) / cell_m
            j0 = int(math.floor(pos + 0.5))
            per_axis.append({j: _normal_cdf((j + 0.5 - pos) / sd) - _normal_cdf((j - 0.5 - pos) / sd)
                             for j in (j0 - 1, j0, j0 + 1)})
    out = np.zeros((height, width))
    for y, wy in per_axis[0].items():
        for x, wx in per_axis[1].items():
            if 0 <= x < width and 0 <= y < height:
                out[y, x] = wy * wx
    return out


def _normal_cdf(z: float) -> float:
    return 0.5 * (1.0 + math.erf(z / math.sqrt(2.0)))


def show_beside(view: np.ndarray, beside: list[Blob], camera_height_m: float, cell: np.ndarray,
                width: int, height: int) -> None:
    """Light, in view, the slot next to the centre that each target in `beside` lies towards
    (the larger of its north and east offsets): targets in the camera's cell that it is not over.

    Why not the centre slot: the policy's world counts a target shown in the agent's own cell as
    found (the agent stands on it), so a target shown there that the camera was not over was a
    find the companion had not made, and the belief swept the field for a target it thought
    gone (flight seed 4: 185 moves against 37 in the grid world). The slot it lies towards is
    where the camera has to go to be over it. Off the field, nothing is lit."""
    for b in beside:
        n, e = b.offset_ne(camera_height_m)
        dy, dx = (-int(np.sign(n)), 0) if abs(n) >= abs(e) else (0, int(np.sign(e)))
        x, y = int(cell[0]) + dx, int(cell[1]) + dy
        if (dy or dx) and 0 <= x < width and 0 <= y < height:
            view[0, 1 + dy, 1 + dx] = 1


def show_cells(view: np.ndarray, cells: list[tuple[int, int]], cell: np.ndarray, width: int, height: int) -> None:
    """Light, in view, the slots of these field cells (x, y) that fall in the view's window
    (3 x 3, or 2 r + 1 a side) around `cell` and on the field."""
    k = view.shape[-1]
    half = k // 2
    for x, y in cells:
        r, c = y - int(cell[1]) + half, x - int(cell[0]) + half
        if 0 <= r < k and 0 <= c < k and 0 <= x < width and 0 <= y < height:
            view[0, r, c] = 1


def valid_moves(cell: np.ndarray, width: int, height: int, n_actions: int = 4) -> np.ndarray:
    return valid_mask(np.asarray(cell)[None], width, height, n_actions)[0]


def level_valid_moves(cell: np.ndarray, level: int, grid: GridConfig) -> np.ndarray:
    """(7,) bool: the moves of a field with altitude levels, as the grid world's valid_actions:
    the four that stay on the field, stay for moving targets only, climb below the top level,
    descend above level 1."""
    v = valid_mask(np.asarray(cell)[None], grid.width, grid.height, LEVEL_ACTIONS)[0]
    v[Action.N] = grid.moving
    v[Action.CLIMB] = level < grid.levels
    v[Action.DESCEND] = level > 1
    return v
