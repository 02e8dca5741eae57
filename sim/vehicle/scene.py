"""The field a vehicle searches, shared by our SITL (sim.mavlink.sitl) and the worlds that real
autopilots fly (sim.bridges.world): the episode (targets, their motion, the spawn cell), home
at the spawn point, the rendered paddock and the downward camera, the targets' truth in time.

Built in two steps, as the SITL always did: the geometry (episode, home) first, then
`attach(client)` puts the field into the PyBullet world the vehicle flies in (or a render-only
one) and makes the camera.
"""

from __future__ import annotations

import numpy as np

from sim.gridworld import GridConfig, GridFrame, cell_to_ned, sample_episodes

from .geo import HomePosition

#: the resolutions a simulated camera may have (pixels a side; `sitl --camera-px`): below 16 a
#: cow seen from 3.5 m is a few pixels, above 1024 a frame is megabytes over MAVLink's image
#: protocol (ENCAPSULATED_DATA, 253 bytes a packet)
CAMERA_PX_RANGE = (16, 1024)
#: the ground beyond the grid's border cells (cells): from 8.17 m (altitude level 3) the 100 deg
#: camera sees 9.7 m from its nadir, 5 cells; 4, enough at 3.5 m, showed the void (white) there.
#: The frames at 2.5-4.5 m are the same to the pixel with 4 or 8 (200 rendered).
MARGIN_CELLS = 8


def check_camera_px(px: object) -> int:
    """The camera's resolution (square frames, pixels a side), validated; the message names it."""
    lo, hi = CAMERA_PX_RANGE
    if isinstance(px, bool) or not isinstance(px, int | np.integer) or not lo <= int(px) <= hi:
        raise ValueError(f"camera_px must be a whole number of pixels in {lo}..{hi} (got {px!r})")
    return int(px)


class FieldScene:
    def __init__(self, grid: GridConfig, field_origin: HomePosition, episode_seed: int, target_step_s: float,
                 polygon=None, spawn_cell: tuple[int, int] | None = None) -> None:
        """field_origin: cell (0, 0)'s centre; home becomes the spawn point, and the field's
        cell (0, 0) lies at -spawn in local NED. polygon: a real field (`sim.field.PolygonField`,
        its grid the same as `grid`'s and its origin field_origin): the grid at its heading, the
        spawn cell and the targets on its searchable cells (the largest 4-connected part, which
        a vehicle never crossing a no-fly zone can reach), the ground rendered as its polygon;
        None, today's north-aligned rectangle. spawn_cell: where the vehicle starts (x, y), None:
        the episode's start cell (a fleet's other vehicles start elsewhere on one field)."""
        self.grid = grid
        self.target_step_s = target_step_s
        self.polygon = polygon
        #: cell <-> field NED (about cell (0, 0)): the one mapping (sim.gridworld.coords.GridFrame)
        self.frame = GridFrame(0.0 if polygon is None else float(polygon.heading_deg))
        if polygon is None:
            self.episode = sample_episodes(grid, 1, episode_seed)
        else:
            from sim.gridworld.masks import largest_component

            if (polygon.width, polygon.height, polygon.cell_m) != (grid.width, grid.height, 2.0):
                raise ValueError(f"the polygon field's grid ({polygon.width} x {polygon.height} of {polygon.cell_m} m) "
                                 f"is not the scene's ({grid.width} x {grid.height} of 2 m)")
            self.episode = sample_episodes(grid, 1, episode_seed, mask=largest_component(np.asarray(polygon.mask)))
        if spawn_cell is not None:
            x, y = (int(v) for v in spawn_cell)
            if not (0 <= x < grid.width and 0 <= y < grid.height):
                raise ValueError(f"spawn_cell {spawn_cell} is off the {grid.width} x {grid.height} field")
            if self.episode.mask is not None and not self.episode.mask[0][y, x]:
                raise ValueError(f"spawn_cell {spawn_cell} is not a searchable cell of the field")
            self.episode.agent[0] = (x, y)
        spawn_ne = cell_to_ned(self.episode.agent[0]) if polygon is None else self.frame.cell_to_ned(self.episode.agent[0])
        self.field_origin = HomePosition(field_origin.lat_deg, field_origin.lon_deg, field_origin.alt_m)
        self.home = HomePosition(*self.field_origin.ned_to_geodetic(np.array([spawn_ne[0], spawn_ne[1], 0.0])))
        self.spawn_ne = spawn_ne
        self.field = None
        self.cam = None
        self.motion_t0: float | None = None  # simulated time of the first arming

    def attach(self, client: int, seed: int, edge: bool, camera_px: int) -> None:
        """Render the field into PyBullet world `client` (centred on the spawn point) and make
        the downward camera. The ground reaches MARGIN_CELLS beyond the grid, so a camera over a
        border cell sees track, not the void, from any level's height."""
        from .camera import DownCamera
        from .field import Field

        g = self.grid
        camera_px = check_camera_px(camera_px)
        if self.polygon is None:
            self.field = Field(client, g.width, g.height, g.n_targets, seed=seed, origin=self.episode.agent[0],
                               edge=edge, margin_cells=MARGIN_CELLS)
            self.cam = DownCamera(client, camera_px, camera_px)
            return
        outer, rings = self.polygon.rings_ne()
        no_fly = [(z.kind, r) for z, r in zip(self.polygon.no_fly, rings, strict=True)]
        self.field = Field(client, g.width, g.height, g.n_targets, seed=seed, origin=self.episode.agent[0], edge=edge,
                           margin_cells=MARGIN_CELLS, frame=self.frame, polygon=(outer, no_fly))
        self.cam = DownCamera(client, camera_px, camera_px, heading_deg=self.frame.heading_deg)

    def note_armed(self, t: float, armed: bool) -> None:
        """The targets start moving at the first arming."""
        if self.motion_t0 is None and armed:
            self.motion_t0 = t

    def target_cells(self, t: float) -> np.ndarray:
        """Targets' cells at t, moving smoothly between grid steps: one step per target_step_s
        of simulated time since the vehicle first armed (still before), holding the last
        position after the episode's t_e steps."""
        ep = self.episode
        if ep.paths is None:
            return ep.targets[0].astype(float)
        if self.motion_t0 is None:
            return ep.paths[0, 0].astype(float)
        t = max(t - self.motion_t0, 0.0) / self.target_step_s
        k = int(np.floor(t))
        a = ep.paths[0, min(k, ep.paths.shape[1] - 1)]
        b = ep.paths[0, min(k + 1, ep.paths.shape[1] - 1)]
        return a + (b - a) * (t - k)

    def vehicle_cell(self, position_ned: np.ndarray) -> np.ndarray:
        """The true cell under a vehicle at local NED position_ned (fractional)."""
        ned = position_ned[:2] + self.spawn_ne
        if self.polygon is not None:
            return self.frame.ned_to_cell(ned)
        return np.array([ned[1] / 2.0, -ned[0] / 2.0])

    def field_ne(self, position_ned: np.ndarray) -> tuple[float, float]:
        """True north, east in the field's frame (from cell (0, 0)): the scorer's truth."""
        return float(position_ned[0] + self.spawn_ne[0]), float(position_ned[1] + self.spawn_ne[1])

    def update_targets(self, t: float) -> None:
        if self.field is not None:
            self.field.set_targets(self.target_cells(t))

    def render(self, t: float, position_ned: np.ndarray, yaw: float,
               attitude_rad: tuple[float, float, float] | None = None) -> np.ndarray:
        """The camera's frame at simulated time t from position_ned (the targets where they
        are at t); attitude_rad: the gimbal's residual pointing error (None: none, as flown)."""
        if self.cam is None:
            raise RuntimeError("FieldScene.render before attach(): no camera")
        self.update_targets(t)
        return self.cam.render(position_ned, yaw, attitude_rad)
