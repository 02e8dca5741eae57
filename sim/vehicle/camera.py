"""The downward camera: 100 deg field of view, 50 x 50 px by default (any size: `sitl
--camera-px`), rendered headless with PyBullet's software renderer. Image top is the grid's f (-y), image
right its r (+x): north and east on today's grid, the grid's heading on a real field's.

At 3.5 m the footprint is 2 * 3.5 * tan(50 deg) = 8.3 m: about four 2 m cells, a little more
than the grid world's 3 x 3 view, as in the paper's Gazebo setup (Section VI-C). Higher, it
grows with the height (5.83 m: 13.9 m for a 5 x 5 view, 8.17 m: 19.5 m for 7 x 7, the same
margin), and a cow spans fewer pixels (`uavsearch detector-curve` measures what that does).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from sim.gridworld import DEFAULT_CELL_M

from .field import Field, cell_to_enu
from .frames import ned_to_enu

ALTITUDE_M = 3.5
#: the camera hangs this far below the airframe's reference point
CAMERA_BELOW_M = 0.06
class DownCamera:
    def __init__(self, client: int, width: int = 50, height: int = 50, fov_deg: float = 100.0,
                 heading_deg: float = 0.0) -> None:
        """heading_deg: the bearing the image's top points at: the gimbal keeps the image aligned
        to the grid, whose -y axis (the move f) points there (a real field's grid, `sim.field`);
        0, north-up as always."""
        if width < 1 or height < 1 or not 1 < fov_deg < 179:
            raise ValueError("camera needs a positive size and 1 < fov < 179 degrees")
        if not np.isfinite(heading_deg):
            raise ValueError(f"camera heading must be finite degrees (got {heading_deg!r})")
        self.cid, self.width, self.height, self.fov = client, width, height, fov_deg
        self.heading_deg = float(heading_deg)
        h = np.radians(self.heading_deg)
        #: the image's top as an ENU direction (east, north, up)
        self._up = [0, 1, 0] if self.heading_deg == 0.0 else [float(np.sin(h)), float(np.cos(h)), 0.0]
        self.proj = p.computeProjectionMatrixFOV(fov_deg, width / height, 0.05, 50.0, physicsClientId=client)

    def render_enu(self, eye_enu: np.ndarray, attitude_rad: tuple[float, float, float] | None = None) -> np.ndarray:
        """(H, W, 3) uint8 from a camera at eye_enu looking straight down, image top north.
        attitude_rad: (roll, pitch, yaw) of the camera off that (the gimbal's residual as the
        vehicle hovers: `missions.detector_curve`); None, exactly nadir and north-up."""
        eye = [float(eye_enu[0]), float(eye_enu[1]), float(eye_enu[2])]
        if attitude_rad is None:
            view = p.computeViewMatrix(eye, [eye[0], eye[1], 0.0], self._up, physicsClientId=self.cid)
        else:
            roll, pitch, yaw = (float(a) for a in attitude_rad)
            q = p.getQuaternionFromEuler([roll, pitch, yaw - float(np.radians(self.heading_deg))])
            rot = np.asarray(p.getMatrixFromQuaternion(q)).reshape(3, 3)
            look, up = rot @ np.array([0.0, 0.0, -1.0]), rot @ np.array([0.0, 1.0, 0.0])
            view = p.computeViewMatrix(eye, [eye[i] + float(look[i]) for i in range(3)], [float(v) for v in up],
                                       physicsClientId=self.cid)
        _, _, rgba, _, _ = p.getCameraImage(
            self.width, self.height, view, self.proj, renderer=p.ER_TINY_RENDERER,
            shadow=0, flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=self.cid,
        )
        return np.asarray(rgba, dtype=np.uint8).reshape(self.height, self.width, 4)[..., :3].copy()

    def render(self, position_ned: np.ndarray, yaw: float = 0.0,
               attitude_rad: tuple[float, float, float] | None = None) -> np.ndarray:
        """(H, W, 3) uint8 from a camera just below the airframe at position_ned. North-up
        (the gimbal keeps the image aligned to the grid, as in the paper's setup); attitude_rad:
        the gimbal's residual pointing error (`render_enu`), None for none (the SITL's)."""
        eye = ned_to_enu(np.asarray(position_ned, dtype=float))
        eye[2] = max(eye[2] - CAMERA_BELOW_M, 0.1)
        return self.render_enu(eye, attitude_rad)


@dataclass(frozen=True)
class WorldState:
    """What an offline render needs: the grid, its targets and how they look."""

    width: int
    height: int
    targets: np.ndarray  # (R, 2) cells, may be fractional
    headings: np.ndarray | None = None
    cell_m: float = DEFAULT_CELL_M


class ViewRenderer:
    """A persistent hidden scene for offline rendering of many views (the +S datasets)."""

    def __init__(self, width: int, height: int, n_targets: int, image: int = 50, seed: int = 0,
                 cell_m: float = DEFAULT_CELL_M) -> None:
        self.cid = p.connect(p.DIRECT)
        self.field = Field(self.cid, width, height, n_targets, cell_m, seed)
        self.camera = DownCamera(self.cid, image, image)
        self.cell_m = cell_m

    def render_view(self, state: WorldState, cell: np.ndarray) -> np.ndarray:
        self.field.set_targets(state.targets, state.headings)
        eye = cell_to_enu(np.asarray(cell, dtype=float), self.cell_m)
        eye[2] = ALTITUDE_M
        return self.camera.render_enu(eye)

    def render_views(self, targets: np.ndarray, agents: np.ndarray, width: int, height: int) -> np.ndarray:
        """targets (n, R, 2), agents (n, 2) -> (n, 3, H, W) uint8 (channels first, for networks)."""
        out = np.empty((len(agents), 3, self.camera.height, self.camera.width), dtype=np.uint8)
        for i, (tg, ag) in enumerate(zip(targets, agents, strict=True)):
            out[i] = self.render_view(WorldState(width, height, tg, cell_m=self.cell_m), ag).transpose(2, 0, 1)
        return out

    def close(self) -> None:
        if p.isConnected(self.cid):
            p.disconnect(self.cid)


def render_view(state: WorldState, cell: np.ndarray, image: int = 50, seed: int = 0) -> np.ndarray:
    """One-off render (opens and closes a scene); use ViewRenderer for many."""
    r = ViewRenderer(state.width, state.height, len(state.targets), image, seed, state.cell_m)
    try:
        return r.render_view(state, cell)
    finally:
        r.close()
