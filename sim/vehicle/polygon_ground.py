"""A polygon field's ground in the PyBullet world: grass inside the field's outer ring, the
headland track outside it (along every edge of the polygon, as a real paddock's fence has a
track beside it), water in its holes (a pond) and a roof over its exclusion polygons (a barn).

Its own module because the rectangle's ground (`sim.vehicle.field.Field`) is two boxes; a
polygon is a triangle mesh (shapely's constrained Delaunay triangulation, holes left out), laid
flat a few millimetres apart so the camera sees each layer where it belongs. The colours are
far from the grass, the track and every coat, so the companion's detector can tell them from
targets (`autopilot_bridge.detection.detector.NOFLY_RGB`, rendered values)."""

from __future__ import annotations

import numpy as np
import pybullet as p

#: a pond's water and a barn's roof (rendered (31, 77, 179) and (97, 107, 148); a black coat's
#: lit side and a white coat's shaded side come no nearer than 60 in RGB)
WATER = (0.12, 0.30, 0.70, 1)
ROOF = (0.38, 0.42, 0.58, 1)
#: heights of the layers' top faces (m): the track box's top lies at -0.02
GRASS_Z, NOFLY_Z = 0.002, 0.004


def triangles(ring_en: np.ndarray, holes_en: list[np.ndarray] = ()) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) east, north ring (not closed) with holes -> (vertices (k, 3) ENU at z 0,
    indices (3 m,)) of a triangle mesh covering it, every triangle counter-clockwise seen from
    above (its face up, which the renderer draws)."""
    import shapely

    poly = shapely.Polygon(ring_en, [h for h in holes_en])
    tris = shapely.constrained_delaunay_triangles(poly)
    verts: list[tuple[float, float]] = []
    index: dict[tuple[float, float], int] = {}
    idx: list[int] = []
    for t in shapely.get_parts(tris):
        pts = np.asarray(t.exterior.coords)[:3]
        a, b, c = pts
        if (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) < 0:
            pts = pts[[0, 2, 1]]
        for q in pts:
            key = (float(q[0]), float(q[1]))
            if key not in index:
                index[key] = len(verts)
                verts.append(key)
            idx.append(index[key])
    v = np.zeros((len(verts), 3))
    v[:, :2] = verts
    return v, np.asarray(idx, dtype=np.int64)


def _flat_mesh(client: int, ring_en: np.ndarray, holes_en: list[np.ndarray], rgba: tuple[float, ...],
               z: float) -> int:
    v, idx = triangles(ring_en, holes_en)
    # every normal straight up: lit as the rectangle's box top is, one shade over the whole field
    # (without them the renderer's interpolated normals shaded the grass in a gradient across a
    # frame, which the detector would read as something on the grass)
    vis = p.createVisualShape(p.GEOM_MESH, vertices=v.tolist(), indices=idx.tolist(),
                              normals=[[0.0, 0.0, 1.0]] * len(v), rgbaColor=list(rgba), physicsClientId=client)
    return p.createMultiBody(0, -1, vis, [0.0, 0.0, z], physicsClientId=client)


def build_polygon_ground(client: int, outer_en: np.ndarray, no_fly: list[tuple[str, np.ndarray]],
                         margin_m: float, track_rgba: tuple[float, ...], grass_rgba: tuple[float, ...]) -> list[int]:
    """The field's ground in world `client`, rings in the world's (east, north) metres: a track
    box reaching margin_m beyond the ring's bounds, the grass mesh over the ring less its holes,
    and a water (hole) or roof (exclusion) mesh over each no-fly ring. Returns the bodies."""
    lo, hi = outer_en.min(axis=0) - margin_m, outer_en.max(axis=0) + margin_m
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[float(half[0]), float(half[1]), 0.01],
                              rgbaColor=list(track_rgba), physicsClientId=client)
    bodies = [p.createMultiBody(0, -1, vis, [float(centre[0]), float(centre[1]), -0.03], physicsClientId=client)]
    holes = [r for kind, r in no_fly if kind == "hole"]
    bodies.append(_flat_mesh(client, outer_en, holes, grass_rgba, GRASS_Z))
    for kind, ring in no_fly:
        bodies.append(_flat_mesh(client, ring, [], WATER if kind == "hole" else ROOF, NOFLY_Z))
    return bodies
