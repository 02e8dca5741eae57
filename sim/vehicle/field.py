"""The field the UAV searches: a grass plane over the grid (2 m cells) and cattle-like
targets built from primitives (torso, head, four legs; random heading and coat), placed and
moved by the grid world's placement and motion models. Visual only: nothing collides.

Round the grass, optionally, the paddock's edge: a headland track of bare earth from the grid's
outer cell borders out (a real field is fenced, a track or stubble beside the fence). The
companion sees it within two cells of the border and registers on it (a position measurement
with no lattice ambiguity: `autopilot_bridge.detection.detector.find_edges`). Without it the ground is
grass to the horizon and only the targets tell the camera where it truly is."""

from __future__ import annotations

import numpy as np
import pybullet as p

from sim.gridworld import DEFAULT_CELL_M, GridFrame, cell_to_ned

from .frames import ned_to_enu

COATS = {
    "black": (0.08, 0.08, 0.08, 1),
    "brown": (0.45, 0.26, 0.12, 1),
    "white": (0.92, 0.90, 0.86, 1),
    "red": (0.62, 0.22, 0.10, 1),
}
GRASS = (0.30, 0.52, 0.18, 1)
#: the headland track round the field: far in colour from the grass and every coat, shaded or not
#: (rendered (176, 157, 109); a white coat's shaded side comes no nearer than 41 in RGB)
EDGE = (0.74, 0.66, 0.46, 1)


def _cow_shape(client: int, coat: tuple[float, ...]) -> int:
    dark = (0.1, 0.08, 0.06, 1)
    parts = [  # (half extents, offset) in the cow frame: x forward, z up
        ((0.70, 0.25, 0.25), (0.0, 0.0, 0.95)),  # torso
        ((0.20, 0.15, 0.15), (0.85, 0.0, 1.10)),  # head
        ((0.06, 0.06, 0.35), (0.50, 0.16, 0.35)),
        ((0.06, 0.06, 0.35), (0.50, -0.16, 0.35)),
        ((0.06, 0.06, 0.35), (-0.50, 0.16, 0.35)),
        ((0.06, 0.06, 0.35), (-0.50, -0.16, 0.35)),
    ]
    return p.createVisualShapeArray(
        shapeTypes=[p.GEOM_BOX] * len(parts),
        halfExtents=[list(h) for h, _ in parts],
        visualFramePositions=[list(o) for _, o in parts],
        rgbaColors=[list(coat), list(coat)] + [list(dark)] * 4,
        physicsClientId=client,
    )


def cell_to_enu(cells: np.ndarray, cell_m: float = DEFAULT_CELL_M) -> np.ndarray:
    ne = cell_to_ned(cells, cell_m)
    return ned_to_enu(np.concatenate([ne, np.zeros(ne.shape[:-1] + (1,))], axis=-1))


class Field:
    def __init__(self, client: int, width: int, height: int, n_targets: int, cell_m: float = DEFAULT_CELL_M,
                 seed: int = 0, margin_cells: int = 4, origin: np.ndarray | None = None,
                 edge: bool = False, frame: GridFrame | None = None,
                 polygon: tuple[np.ndarray, list[tuple[str, np.ndarray]]] | None = None) -> None:
        """origin: the cell at the PyBullet world's origin (SITL puts the spawn cell there).
        edge: the margin round the grid is the headland track (EDGE), not grass.
        frame: the grid's heading (a real field's, `sim.field`; origin (0, 0) = cell (0, 0));
        None, today's north-aligned grid. polygon: the field's outer ring and its no-fly rings
        ((kind, ring)), (n, 2) north, east metres about cell (0, 0): the ground is then grass
        inside the ring, track outside, water or roof in the no-fly zones
        (`sim.vehicle.polygon_ground`); None, the grid's rectangle."""
        self.cid, self.w, self.h, self.cell_m = client, width, height, cell_m
        self.origin = np.zeros(2) if origin is None else np.asarray(origin, dtype=float)
        self.frame = frame
        self.rng = np.random.default_rng([seed, 0xC0A7])
        # the ground covers the grid plus a margin, so the camera never sees the void; with an
        # edge the grass covers the grid's cells only, a little above the track round it
        self.edge = edge
        if polygon is not None:
            self._polygon_ground(polygon, margin_cells, edge)
        else:
            self._rectangle_ground(width, height, cell_m, margin_cells, edge)
        names = list(COATS)
        self.coats = [names[i] for i in self.rng.integers(0, len(names), n_targets)]
        self.headings = self.rng.uniform(-np.pi, np.pi, n_targets)
        self.cows = [
            p.createMultiBody(0, -1, _cow_shape(client, COATS[c]), [0, 0, -50], physicsClientId=client)
            for c in self.coats
        ]

    def _world_ne(self) -> np.ndarray:
        """The PyBullet world's origin (the origin cell's centre) in the field's NED metres."""
        return (self.frame or GridFrame(0.0, self.cell_m)).cell_to_ned(self.origin)

    def _polygon_ground(self, polygon: tuple[np.ndarray, list[tuple[str, np.ndarray]]], margin_cells: int,
                        edge: bool) -> None:
        from .polygon_ground import build_polygon_ground

        o = self._world_ne()
        outer, no_fly = polygon
        en = [(np.asarray(outer) - o)[:, ::-1], [(k, (np.asarray(r) - o)[:, ::-1]) for k, r in no_fly]]
        self.bodies = build_polygon_ground(self.cid, en[0], en[1], margin_cells * self.cell_m,
                                           EDGE if edge else GRASS, GRASS)

    def _rectangle_ground(self, width: int, height: int, cell_m: float, margin_cells: int, edge: bool) -> None:
        client = self.cid
        centre = cell_to_enu(np.array([(width - 1) / 2, (height - 1) / 2]) - self.origin, cell_m)
        outer = [(width + 2 * margin_cells) * cell_m / 2, (height + 2 * margin_cells) * cell_m / 2, 0.01]
        grass = [width * cell_m / 2, height * cell_m / 2, 0.01] if edge else outer
        if edge:
            vis = p.createVisualShape(p.GEOM_BOX, halfExtents=outer, rgbaColor=list(EDGE), physicsClientId=client)
            self.track = p.createMultiBody(0, -1, vis, [centre[0], centre[1], -0.03], physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=grass, rgbaColor=list(GRASS), physicsClientId=client)
        self.ground = p.createMultiBody(0, -1, vis, [centre[0], centre[1], -0.008], physicsClientId=client)

    def set_targets(self, cells: np.ndarray, headings: np.ndarray | None = None) -> None:
        """Place the targets at (fractional) cells; headings in ENU radians."""
        cells = np.asarray(cells, dtype=float).reshape(-1, 2)
        if len(cells) != len(self.cows):
            raise ValueError(f"field has {len(self.cows)} targets, got {len(cells)} cells")
        if headings is not None:
            self.headings = np.asarray(headings, dtype=float)
        if self.frame is None:
            pos = cell_to_enu(cells - self.origin, self.cell_m)
        else:
            ne = self.frame.cell_to_ned(cells) - self._world_ne()
            pos = ned_to_enu(np.concatenate([ne, np.zeros(ne.shape[:-1] + (1,))], axis=-1))
        for body, xyz, yaw in zip(self.cows, pos, self.headings, strict=True):
            q = p.getQuaternionFromEuler([0, 0, float(yaw)])
            p.resetBasePositionAndOrientation(body, [float(xyz[0]), float(xyz[1]), 0.0], q, physicsClientId=self.cid)
