"""From a downward camera frame to the grid view I the policy was trained on.

The camera at 3.5 m with a 100 deg FoV sees 8.3 m, so the 3 x 3 cells around the UAV (6 m)
are the central 36 of 50 pixels. Cattle (black, brown, white, red) sit far from the field's
green in colour. A classical detector on purpose: it is transparent, needs no training data,
and the paper's +S network shows a learned one can replace it.

Two ways to read a frame: `cell_fractions`/`frame_to_view` light a cell's window when enough
of its pixels are not grass; `find_blobs`/`blobs_to_view` (what the flight uses) find each
target as one blob and put it in the one cell its centroid falls in. The window reading
assumes the camera is over the cell's centre; in flight it is off by the GPS bias (0.7 m sd
per axis), so a cow straddled two or three windows, or the centre window missed it. A blob's
offset from the nadir is also GPS-free: it tells where the camera truly is (registration).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..localisation.edges import edge_mask, half_footprint_m


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
    #: colours that are ground, not targets, beside the grass and the track: a real field's
    #: no-fly zones as the camera sees them (NOFLY_RGB: its pond's water, its barn's roof), which
    #: a survey of the field would calibrate as it calibrates the track's; () on a plain paddock
    ground_rgb: tuple[tuple[float, float, float], ...] = ()


#: a polygon field's no-fly zones as rendered (sim.vehicle.polygon_ground: WATER, ROOF); a pixel
#: within edges.EDGE_DISTANCE of one is ground (a coat's nearest pixel is 40 away)
NOFLY_RGB = ((28.0, 71.0, 167.0), (90.0, 100.0, 138.0))


def _targets_mask(f: np.ndarray, cfg: DetectorConfig) -> np.ndarray:
    """(H, W, 3) float -> (H, W) bool: the pixels far from the field's grass in colour, the
    track round the field (`edges.edge_mask`) left out. The grass is the median of the pixels
    that are not track: the field dominates every frame but those over a corner of it, where the
    track fills up to three quarters. The config's ground colours (a field's water and roofs)
    are left out like the track, of the grass's median too."""
    track = edge_mask(f)
    for rgb in cfg.ground_rgb:
        track = track | edge_mask(f, rgb)
    ground = f[~track] if not track.all() else f.reshape(-1, 3)
    grass = np.median(ground.reshape(-1, 3), axis=0)
    return (np.linalg.norm(f - grass, axis=-1) > cfg.colour_distance) & ~track


def cell_fractions(frame: np.ndarray, cfg: DetectorConfig = DetectorConfig()) -> np.ndarray:
    """(H, W, 3) uint8 -> (3, 3) fraction of non-grass pixels per cell (rows: north to south)."""
    h, w = frame.shape[:2]
    px_per_m = w / (2 * half_footprint_m(cfg.altitude_m, cfg.fov_deg))
    f = frame.astype(np.float32)
    off = _targets_mask(f, cfg)
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



# -- blob centroids: where a target is, not how much of a window it fills --------------------
#: a target's visible top (a cow's back, ~1 m) is nearer the camera than the grass, so it
#: appears further out than its ground offset (perspective): pixels per metre of ground offset
#: at camera height H are K_PX_M / (H - TOP_M) for a 50 px frame (rendered cows, 2.5-4.5 m:
#: centroid error 0.11 m rms, max 0.28 m, for blobs inside the frame)
K_PX_M, TOP_M = 21.75, 0.94
#: a blob cut by the frame's edge has its centroid pulled inwards: its target lies about this
#: much further out along the cut axis (rendered: 0.2 m rms after the shift, max 0.45 m)
EDGE_PUSH_M = 0.35
#: a blob cut by the frame's edge whose nearest pixel is further than this from the nadir
#: (the larger of the two axes, m) is a target two cells away whose near end shows: rendered,
#: the cut blobs of targets in the 3 x 3 window reach in to 1.9 m at most, those two cells
#: away 2.0 m at least (it was read as a neighbour: the planner stepped back and forth
#: between two cells chasing it, the demo's moves 29-40)
EDGE_BEYOND_M = 1.95


#: and this much further per ring of a wider window (radius r, flown at 3.5 m (2r + 1) / 3): the
#: window's border is a cell further out per ring and the frame's edge, where blobs are cut,
#: further still. Rendered (tuning seeds 1 and 2, 6000 frames each): the cut blobs of targets in
#: the 5 x 5 window reach in to 4.4 m (95 %), those beyond it from 4.2 m; a cell (2 m) per ring
#: missed 33-34 of ~2000 targets at level 2, 2.5 m 3-4, with as many false alarms (13-16);
#: 3 m added 5 false alarms.
EDGE_BEYOND_STEP_M = 2.5


def edge_beyond_m(radius: int) -> float:
    """EDGE_BEYOND_M for a window of this radius (cells): EDGE_BEYOND_STEP_M further per ring."""
    return EDGE_BEYOND_M + EDGE_BEYOND_STEP_M * (radius - 1)


#: smaller blobs are specks (a leg at the frame's edge, rendering noise): ignored
MIN_BLOB_PX = 4
#: a blob inside the frame (not cut by its edge) smaller than this is no target: a whole cow
#: inside the frame is 65 px or more, a part split off two touching ones 16 or more; the legs
#: of a cow whose back is beyond the frame show inside it (perspective: the legs are lower, so
#: nearer the nadir in the image) as specks of 4-7 px, each read as a target in the next cell
#: (flight seed 59: the policy went back and forth to an empty cell for 290 moves)
MIN_WHOLE_PX = 12
#: a whole blob's offset error (`Blob.fuse_sd_m`): at the nadir, and per metre out
WHOLE_SD_M, WHOLE_SD_PER_M = 0.1, 0.08
#: the camera hangs this far below the airframe's reference point (sim.vehicle.camera)
CAMERA_BELOW_M = 0.06


#: the camera height (m) and frame width (px) the pixel sizes in this module were calibrated at
CAL_HEIGHT_M, CAL_WIDTH_PX = 3.5 - CAMERA_BELOW_M, 50
#: K_PX_M / (H - TOP_M) was fitted at 2.5-4.5 m; flown higher it read whole blobs' offsets short
#: by a scale that grows with the height (rendered, 8.1 m: -0.26 m at 6-8 m out, -3.7 %): the
#: pixels per metre are divided by 1 + this * (H - CAL_HEIGHT_M). Fitted on 6775 whole blobs at
#: heights round the three levels' (tuning seeds 1 and 2; the table is measured on 2026): 8.1 m,
#: 6-8 m out, bias -0.26 -> -0.01 m, rms 0.46 -> 0.40 m; 5.8 m, 2-4 m out, -0.06 -> -0.01 m.
#: Exactly 1 at CAL_HEIGHT_M (today's flights to the bit).
HEIGHT_SCALE_PER_M = 0.0081


def px_per_m(camera_height_m: float, width_px: int = 50) -> float:
    """Pixels per metre of ground offset for a target's top, the camera at this height."""
    return (K_PX_M * (width_px / 50.0) / max(camera_height_m - TOP_M, 0.3)
            / (1.0 + HEIGHT_SCALE_PER_M * (camera_height_m - CAL_HEIGHT_M)))


def pixel_scale(camera_height_m: float, width_px: int) -> float:
    """A target's linear size in pixels against the calibration's (1.0 exactly for a 50 px frame
    from 3.44 m): pixel counts scale with its square."""
    return px_per_m(camera_height_m, width_px) / px_per_m(CAL_HEIGHT_M, CAL_WIDTH_PX)


@dataclass(frozen=True)
class BlobSizes:
    """The pixel counts a frame's blobs are judged by (`find_blobs`), for one pixel scale."""

    min_blob: float
    min_whole: float
    core_min: float
    coat_part: float
    erosion: int  # erosion passes that part touching targets (`_split_touching`)

    @classmethod
    def at(cls, scale: float) -> BlobSizes:
        """The calibration's sizes scaled by scale**2 (areas), with floors where a frame has too
        few pixels per target to part or weigh them (a speck of 1-2 px is rendering noise at any
        height); scale 1 gives the calibration's integers exactly."""
        a = scale * scale
        return cls(max(MIN_BLOB_PX * a, MIN_BLOB_FLOOR_PX), max(MIN_WHOLE_PX * a, MIN_BLOB_FLOOR_PX),
                   max(CORE_MIN_PX * a, CORE_FLOOR_PX), max(COAT_PART_PX * a, CORE_FLOOR_PX),
                   max(1, int(round(scale))))


@dataclass(frozen=True)
class Blob:
    """One target seen in a frame, in pixels: centroid (row, col) from the frame's centre
    (rows grow southwards, columns eastwards), size, and which frame edges cut it."""

    row: float
    col: float
    pixels: int
    cut: tuple[bool, bool, bool, bool]  # north, south, west, east
    width_px: int = 50
    #: the blob's pixel nearest the frame's centre: its distance, the larger of the two axes
    inner_px: float = 0.0

    @property
    def at_edge(self) -> bool:
        return any(self.cut)

    @property
    def cut_axes(self) -> tuple[bool, bool]:
        """Per axis (north, east): is the blob cut by a frame edge across it? Its centre along
        such an axis is censored (the target runs on out of the frame)."""
        cn, cs, cw, ce = self.cut
        return cn or cs, cw or ce

    @property
    def cut_sides(self) -> tuple[int, int]:
        """Per axis (north, east): +1 where the blob is cut by the north (east) edge alone, -1 by
        the south (west) edge alone, else 0: the side its target runs on out of the frame."""
        cn, cs, cw, ce = self.cut
        return int(cn) - int(cs) if cn != cs else 0, int(ce) - int(cw) if ce != cw else 0

    @property
    def sd_m(self) -> float:
        """Standard deviation of the offset per axis (the calibration's rms, widened at edges)."""
        return 0.4 if self.at_edge else 0.3

    def fuse_sd_m(self, camera_height_m: float) -> float:
        """The standard deviation its offset is fused with as a position measurement (m, per
        axis). Flown (seeds 0-39, 1011 blobs against the truth): 0.11 m rms within 1 m of the
        nadir, 0.17 m at 1-2 m (the camera's height error scales the offset: the barometer
        drifts 0.16 m sd), 0.35 m at 2-3 m, where most blobs are cut by the frame's edge. The
        flat 0.3 m (`sd_m`) left the posterior wider than its errors after registrations
        (normalised squared error 0.64-0.72 per axis where 1 is honest)."""
        if self.at_edge:
            return self.sd_m
        r = float(np.hypot(*self.offset_ne(camera_height_m)))
        return float(np.hypot(WHOLE_SD_M, WHOLE_SD_PER_M * r))

    def beyond_view(self, camera_height_m: float, radius: int = 1) -> bool:
        """A target outside the (2 radius + 1)^2 window whose near end shows at the frame's edge
        (EDGE_BEYOND_M for radius 1, further per ring: `edge_beyond_m`)."""
        return self.at_edge and self.inner_px / px_per_m(camera_height_m, self.width_px) > edge_beyond_m(radius)

    def offset_ne(self, camera_height_m: float) -> tuple[float, float]:
        """The target's offset from the camera's nadir (north, east metres): GPS-free."""
        k = px_per_m(camera_height_m, self.width_px)
        cn, cs, cw, ce = self.cut
        return (-self.row / k + EDGE_PUSH_M * (int(cn) - int(cs)),
                self.col / k + EDGE_PUSH_M * (int(ce) - int(cw)))


def find_blobs(frame: np.ndarray, cfg: DetectorConfig = DetectorConfig(),
               camera_height_m: float | None = None) -> list[Blob]:
    """(H, W, 3) uint8 -> the targets in the frame as blobs of non-grass pixels (8-connected).
    A target that straddles a cell border is one blob with one centre, not two half-lit windows.

    camera_height_m: the camera's height over the field as flown (the barometer/EKF altitude
    less CAMERA_BELOW_M); None: the config's altitude_m less CAMERA_BELOW_M (3.44 m by default,
    today's flights). The blob sizes follow it (`BlobSizes.at(pixel_scale(...))`)."""
    from scipy import ndimage

    h, w = frame.shape[:2]
    height = cfg.altitude_m - CAMERA_BELOW_M if camera_height_m is None else float(camera_height_m)
    if not (math.isfinite(height) and height > 0):
        raise ValueError(f"camera_height_m must be a positive height in metres (got {camera_height_m})")
    sizes_px = BlobSizes.at(pixel_scale(height, w))
    f = frame.astype(np.float32)
    off = _targets_mask(f, cfg)
    lab, n = _split_touching(off, sizes_px)
    lab, n = _split_coats(f, lab, n, sizes_px.coat_part)
    lab, n = _split_long(lab, n, LONG_SD_M * px_per_m(height, w), sizes_px.core_min)
    if n == 0:
        return []
    idx = np.arange(1, n + 1)
    sizes = ndimage.sum_labels(off, lab, idx)
    centres = ndimage.center_of_mass(off, lab, idx)
    out = []
    for i, (size, (cy, cx), (ys, xs)) in enumerate(zip(sizes, centres, ndimage.find_objects(lab), strict=True)):
        cut = (ys.start == 0, ys.stop == h, xs.start == 0, xs.stop == w)
        if size >= sizes_px.min_blob and (any(cut) or size >= sizes_px.min_whole):
            inner = 0.0
            if any(cut):  # only cut blobs need it
                py, px = np.nonzero(lab[ys, xs] == i + 1)
                inner = float(np.min(np.maximum(np.abs(py + ys.start - (h - 1) / 2), np.abs(px + xs.start - (w - 1) / 2))))
            out.append(Blob(float(cy - (h - 1) / 2), float(cx - (w - 1) / 2), int(size), cut, w, inner))
    return out


#: a part of a blob that survives the erosion counts as a target of its own from this many
#: pixels (without this floor the erosion cut a cow's head off at the neck, 8-11 px, in 7 of 240
#: rendered single cows; with it none)
CORE_MIN_PX = 16
#: floors of the scaled sizes (`BlobSizes.at`) for frames with few pixels per target (high up,
#: or a coarse camera): a blob of fewer pixels is noise, a core or coat part of fewer is no part
MIN_BLOB_FLOOR_PX, CORE_FLOOR_PX = 2, 4


def _split_touching(off: np.ndarray, sizes_px: BlobSizes | None = None) -> tuple[np.ndarray, int]:
    """Label the non-grass pixels, one label per target. Targets in neighbouring cells can
    touch in the frame (a cow is 1.75 m long head to tail on a 2 m lattice, and its back, 1 m up,
    is magnified 1.4x): one blob, one centroid between the two. The mask is eroded once so the
    narrow contact gives way, its parts labelled (8-connected), and every pixel given the label
    of the nearest part. sizes_px: the sizes at the frame's pixel scale (None: the calibration's);
    a finer frame is eroded as many times as it has pixels per calibration pixel."""
    from scipy import ndimage

    sizes_px = sizes_px or BlobSizes.at(1.0)
    eight = np.ones((3, 3), bool)
    core = ndimage.binary_erosion(off, structure=eight, iterations=sizes_px.erosion)
    lab, n = ndimage.label(core, structure=eight)
    if n:  # a head cut off at the neck is not a target: small cores join their neighbour
        small = np.flatnonzero(ndimage.sum_labels(core, lab, np.arange(1, n + 1)) < sizes_px.core_min) + 1
        core &= ~np.isin(lab, small)
        lab, n = ndimage.label(core, structure=eight)
    if n == 0:
        return ndimage.label(off, structure=eight)
    # nearest core pixel for every pixel; pixels of a blob with no core keep their own label
    _, (iy, ix) = ndimage.distance_transform_edt(lab == 0, return_indices=True)
    near = lab[iy, ix]
    whole, m = ndimage.label(off, structure=eight)
    out = np.where(off, near, 0)
    has_core = ndimage.maximum(core, whole, np.arange(1, m + 1)) > 0
    for k in np.flatnonzero(~has_core) + 1:  # specks too thin to survive the erosion
        n += 1
        out[whole == k] = n
    return out, n


#: coats (sim.vehicle.field.COATS) as rendered, lit from above and on shaded sides: a blob
#: of two coats is two touching targets
COAT_RGB = np.array([[c * 255 * k for c in rgb] for rgb in ((0.08, 0.08, 0.08), (0.45, 0.26, 0.12), (0.92, 0.90, 0.86),
                                                             (0.62, 0.22, 0.10)) for k in (0.93, 0.7)])
#: a coat's part of a blob counts as a target of its own from this many pixels (a single cow
#: inside the frame: 69-127 px; legs and shadows in another colour: a few)
COAT_PART_PX = 20


def _split_coats(f: np.ndarray, lab: np.ndarray, n: int, part_px: float = COAT_PART_PX) -> tuple[np.ndarray, int]:
    """Split blobs made of two coats' colours, each over COAT_PART_PX pixels, into one label
    per coat (touching targets whose contact the erosion did not break); the stray pixels of
    other colours go to the nearest part."""
    from scipy import ndimage

    if n == 0:
        return lab, n
    d = np.linalg.norm(f[..., None, :] - COAT_RGB[None, None], axis=-1)
    coat = np.where(lab > 0, np.argmin(d, axis=-1) // 2, -1)
    out, m = lab.copy(), n
    for k in range(1, n + 1):
        inside = lab == k
        classes, counts = np.unique(coat[inside], return_counts=True)
        major = classes[counts >= part_px]
        if len(major) < 2:
            continue
        parts = np.zeros_like(lab)
        for c in major:
            m += 1
            parts[inside & (coat == c)] = m
        _, (iy, ix) = ndimage.distance_transform_edt(parts == 0, return_indices=True)
        out[inside] = parts[iy, ix][inside]
    if m == n:
        return out, n
    used, compact = np.unique(out, return_inverse=True)  # labels 1..count again
    return compact.reshape(out.shape), len(used) - 1


#: a blob whose pixels spread further than this along their long axis (sd, metres of a target's
#: top) is two targets of one coat that touch (neither the erosion nor the coats part them):
#: rendered single cows reach 0.63 m (1121 frames, any heading, the camera up to 0.9 m off the
#: cell); two touching neighbours 0.7-1.0 m. The barometer's drift (0.2 m sd) scales a frame by
#: 8 %, inside the margin. One such blob (flight seed 62) centred between two cows registered
#: the frame a row off, and the second cow was hunted for 100 moves.
LONG_SD_M = 0.7


def _split_long(lab: np.ndarray, n: int, long_sd_px: float, core_min_px: float = CORE_MIN_PX) -> tuple[np.ndarray, int]:
    """Split each blob longer than long_sd_px (sd along its principal axis) into two by 2-means
    on its pixels' positions, seeded one sd either side of its centre along that axis."""
    if n == 0:
        return lab, n
    out, m = lab.copy(), n
    for k in range(1, n + 1):
        ys, xs = np.nonzero(lab == k)
        if len(ys) < 2 * core_min_px:
            continue
        pts = np.stack([ys, xs], axis=1).astype(float)
        centre = pts.mean(axis=0)
        evals, evecs = np.linalg.eigh(np.cov(pts.T))
        sd = float(np.sqrt(max(evals[-1], 0.0)))
        if sd <= long_sd_px:
            continue
        seeds = centre + np.outer([-sd, sd], evecs[:, -1])
        for _ in range(10):
            side = np.linalg.norm(pts[:, None] - seeds[None], axis=-1).argmin(axis=1)
            if side.min() == side.max():
                break
            new = np.stack([pts[side == j].mean(axis=0) for j in (0, 1)])
            if np.allclose(new, seeds):
                break
            seeds = new
        if min(int((side == 0).sum()), int((side == 1).sum())) < core_min_px:
            continue
        m += 1
        out[ys[side == 1], xs[side == 1]] = m
    return out, m


def window_cells(blobs: list[Blob], camera_offset_ne: tuple[float, float] | np.ndarray, camera_height_m: float,
                 radius: int = 1, cell_m: float = 2.0) -> list[tuple[int, int] | None]:
    """Each blob's slot (row, col) in the (2 radius + 1)^2 window a level of this radius sees
    (rows north to south, the nadir cell at (radius, radius)), the camera camera_offset_ne (north,
    east m) from the nadir cell's centre; None for a blob whose centre falls outside the window or
    that is the near end of a target beyond it (`Blob.beyond_view`). The cell is the one the
    blob's centre falls in, as `autopilot_bridge.detection.view.blob_cells` reads it for radius 1."""
    if radius < 0:
        raise ValueError(f"radius must be >= 0 cells (got {radius})")
    out: list[tuple[int, int] | None] = []
    for b in blobs:
        if b.beyond_view(camera_height_m, max(radius, 1)):  # radius 0: a 1 x 1 window
            out.append(None)
            continue
        dn, de = b.offset_ne(camera_height_m)
        n, e = float(camera_offset_ne[0]) + dn, float(camera_offset_ne[1]) + de
        dx, dy = int(np.floor(e / cell_m + 0.5)), int(np.floor(-n / cell_m + 0.5))
        out.append((dy + radius, dx + radius) if max(abs(dx), abs(dy)) <= radius else None)
    return out


def blobs_to_window(blobs: list[Blob], camera_offset_ne: tuple[float, float] | np.ndarray, camera_height_m: float,
                    radius: int = 1, cell_m: float = 2.0) -> np.ndarray:
    """(2 radius + 1, 2 radius + 1) bool: the window's cells some blob lights (`window_cells`)."""
    out = np.zeros((2 * radius + 1, 2 * radius + 1), dtype=bool)
    for rc in window_cells(blobs, camera_offset_ne, camera_height_m, radius, cell_m):
        if rc is not None:
            out[rc] = True
    return out
