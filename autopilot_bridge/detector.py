"""From a downward camera frame to the grid view I the policy was trained on.

The camera at 3.5 m with a 100 deg FoV sees 8.3 m, so the 3 x 3 cells around the UAV (6 m)
are the central 36 of 50 pixels. A cell holds a target when enough of its pixels are not
grass: cattle (black, brown, white, red) sit far from the field's green in colour. A classical
detector on purpose: it is transparent, needs no training data, and the paper's +S network
shows a learned one can replace it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.gridworld import valid_mask


@dataclass(frozen=True)
class DetectorConfig:
    altitude_m: float = 3.5
    fov_deg: float = 100.0
    cell_m: float = 2.0
    #: fraction of a neighbouring cell's pixels that must be non-grass to call it a target
    neighbour_fraction: float = 0.10
    #: stricter for the cell below (it decides "found"); a neighbour's head must not count
    centre_fraction: float = 0.20
    colour_distance: float = 70.0


def cell_fractions(frame: np.ndarray, cfg: DetectorConfig = DetectorConfig()) -> np.ndarray:
    """(H, W, 3) uint8 -> (3, 3) fraction of non-grass pixels per cell (rows: north to south)."""
    h, w = frame.shape[:2]
    footprint = 2 * cfg.altitude_m * np.tan(np.radians(cfg.fov_deg / 2))
    px_per_m = w / footprint
    f = frame.astype(np.float32)
    grass = np.median(f.reshape(-1, 3), axis=0)  # the field dominates every frame
    off = np.linalg.norm(f - grass, axis=-1) > cfg.colour_distance
    out = np.zeros((3, 3))
    for r in range(3):
        for c in range(3):
            y0 = int(round(h / 2 + (r - 1.5) * cfg.cell_m * px_per_m))
            x0 = int(round(w / 2 + (c - 1.5) * cfg.cell_m * px_per_m))
            y1 = int(round(y0 + cfg.cell_m * px_per_m))
            x1 = int(round(x0 + cfg.cell_m * px_per_m))
            out[r, c] = off[max(y0, 0) : y1, max(x0, 0) : x1].mean()
    return out


def frame_to_view(frame: np.ndarray, cell: np.ndarray, width: int, height: int,
                  cfg: DetectorConfig = DetectorConfig()) -> np.ndarray:
    """A camera frame over `cell` -> the (3, 3, 3) uint8 view {target, off-map, agent}."""
    frac = cell_fractions(frame, cfg)
    target = frac > cfg.neighbour_fraction
    target[1, 1] = frac[1, 1] > cfg.centre_fraction
    dy, dx = np.meshgrid(np.arange(-1, 2), np.arange(-1, 2), indexing="ij")
    ys, xs = cell[1] + dy, cell[0] + dx
    inside = (ys >= 0) & (ys < height) & (xs >= 0) & (xs < width)
    view = np.zeros((3, 3, 3), dtype=np.uint8)
    view[0] = target & inside
    view[1] = ~inside
    view[2, 1, 1] = 1
    return view


def valid_moves(cell: np.ndarray, width: int, height: int, n_actions: int = 4) -> np.ndarray:
    return valid_mask(np.asarray(cell)[None], width, height, n_actions)[0]
