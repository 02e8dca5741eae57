"""From the detector's blobs to the policy's 3 x 3 view I (target, off-map, agent channels): each
target lights the one cell its centre falls in with the camera where the posterior says, found
targets where they were found, a new one beside the camera in the slot it lies towards, and a
target two cells out, whose near end shows at the frame's edge, as a likelihood over cells.
Split from the detector (which finds the blobs in a frame) so each module holds one concern.
"""

from __future__ import annotations

import math

import numpy as np

from sim.gridworld import valid_mask

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
                  width: int, height: int) -> np.ndarray:
    """The (3, 3, 3) uint8 view {target, off-map, agent} around `cell` from the blobs' cells
    (each target lights exactly one slot; targets outside the 3 x 3 window, and edge blobs of
    targets two cells away, are not shown)."""
    dy, dx = np.meshgrid(np.arange(-1, 2), np.arange(-1, 2), indexing="ij")
    ys, xs = cell[1] + dy, cell[0] + dx
    inside = (ys >= 0) & (ys < height) & (xs >= 0) & (xs < width)
    view = np.zeros((3, 3, 3), dtype=np.uint8)
    near = [b for b in blobs if not b.beyond_view(camera_height_m)]
    show_cells(view, blob_cells(near, camera_ne, camera_height_m), cell, width, height)
    view[1] = ~inside
    view[2, 1, 1] = 1
    return view


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
    """Light, in view, the slots of these field cells (x, y) that fall in the 3 x 3 window
    around `cell` and on the field."""
    for x, y in cells:
        r, c = y - int(cell[1]) + 1, x - int(cell[0]) + 1
        if 0 <= r < 3 and 0 <= c < 3 and 0 <= x < width and 0 <= y < height:
            view[0, r, c] = 1


def valid_moves(cell: np.ndarray, width: int, height: int, n_actions: int = 4) -> np.ndarray:
    return valid_mask(np.asarray(cell)[None], width, height, n_actions)[0]
