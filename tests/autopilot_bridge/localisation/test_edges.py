"""The field's edge in rendered frames (autopilot_bridge.localisation.edges): a real PyBullet field with its
headland track, the real downward camera, borders read against where they truly are."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from autopilot_bridge.detection.detector import find_blobs
from autopilot_bridge.localisation.edges import (
    border_ne,
    find_edges,
    find_ring_edges,
    half_footprint_m,
    ring_normals,
)
from sim.gridworld import GridFrame, cell_to_ned
from sim.vehicle.camera import DownCamera
from sim.vehicle.field import Field, cell_to_enu

W, H = 10, 8


@pytest.fixture(scope="module")
def scene():
    cid = p.connect(p.DIRECT)
    try:
        yield Field(cid, W, H, 2, seed=3, edge=True), DownCamera(cid, 50, 50)
    finally:
        p.disconnect(cid)


def _frame(scene, cell: tuple[float, float], height: float) -> np.ndarray:
    _, camera = scene
    eye = cell_to_enu(np.asarray(cell, dtype=float))
    eye[2] = height
    return camera.render_enu(eye)


def test_borders_in_view_are_read_to_a_decimetre_at_any_height(scene) -> None:
    field, _ = scene
    field.set_targets(np.array([[4.0, 3.0], [5.0, 4.0]]))  # inside, away from the borders
    rng = np.random.default_rng(7)
    errors, in_view = [], 0
    for _ in range(60):
        # near a random border or corner, anywhere from 3 to 4 m up
        cell = np.array([rng.choice([rng.uniform(-0.3, 1.5), rng.uniform(7.5, 9.3)]),
                         rng.choice([rng.uniform(-0.3, 1.5), rng.uniform(5.5, 7.3), rng.uniform(2, 5)])])
        height = float(rng.uniform(3.0, 4.0))
        seen = {(e.axis, e.side): e for e in find_edges(_frame(scene, cell, height), height)}
        ne = cell_to_ned(cell)
        reach = half_footprint_m(height)
        for axis in (0, 1):
            for side in (1, -1):
                d = border_ne(axis, side, W, H) - ne[axis]
                if abs(d) < reach - 0.3:
                    in_view += 1
                    assert (axis, side) in seen, (cell, height, axis, side)
                if (axis, side) in seen:
                    assert abs(d) < reach, "a border beyond the frame is never seen"
                    errors.append(seen[(axis, side)].offset_m - d)
    errors = np.array(errors)
    assert in_view > 40 and len(errors) >= in_view
    assert abs(errors.mean()) < 0.03 and errors.std() < 0.08 and np.abs(errors).max() < 0.15


def test_no_border_inside_the_field_and_a_cow_on_the_border_is_not_one(scene) -> None:
    field, _ = scene
    height = 3.44
    # mid-field: grass and a cow, no border
    field.set_targets(np.array([[4.0, 4.0], [5.0, 3.0]]))
    assert find_edges(_frame(scene, (4.3, 3.6), height), height) == []
    # a cow in the corner cell, seen over the track (its back magnified outwards): the one
    # cow is one blob, the track no target, and each border read where it is
    field.set_targets(np.array([[9.0, 7.0], [0.0, 0.0]]), headings=np.array([0.4, 1.2]))
    frame = _frame(scene, (8.6, 6.7), height)
    blobs = find_blobs(frame)
    assert len(blobs) == 1
    seen = {(e.axis, e.side): e.offset_m for e in find_edges(frame, height)}
    ne = cell_to_ned(np.array([8.6, 6.7]))
    assert set(seen) == {(0, -1), (1, 1)}
    assert abs(seen[(0, -1)] - (border_ne(0, -1, W, H) - ne[0])) < 0.12
    assert abs(seen[(1, 1)] - (border_ne(1, 1, W, H) - ne[1])) < 0.12


def test_without_the_edge_nothing_is_read() -> None:
    cid = p.connect(p.DIRECT)
    try:
        Field(cid, W, H, 1, seed=1).set_targets(np.array([[9.0, 7.0]]))
        eye = cell_to_enu(np.array([9.0, 7.0]))
        eye[2] = 3.44
        frame = DownCamera(cid, 50, 50).render_enu(eye)
    finally:
        p.disconnect(cid)
    assert find_edges(frame, 3.44) == []
    assert len(find_blobs(frame)) == 1


# a polygon field's edges at any angle: a quadrilateral whose sides run 14-76 deg off its grid
RING_NE = np.array([[1.0, -1.0], [5.0, 15.0], [-11.0, 19.0], [-15.0, 2.0]])  # north, east about cell (0, 0)
HEADING = 10.0


@pytest.fixture(scope="module")
def polygon_scene():
    cid = p.connect(p.DIRECT)
    try:
        frame = GridFrame(HEADING, 2.0)
        field = Field(cid, 10, 9, 2, seed=3, edge=True, frame=frame, polygon=(RING_NE, []))
        yield field, DownCamera(cid, 50, 50, heading_deg=HEADING), frame
    finally:
        p.disconnect(cid)


def _polygon_frame(polygon_scene, camera_grid: np.ndarray, height: float) -> np.ndarray:
    _, camera, frame = polygon_scene
    ne = frame.grid_to_ned(camera_grid)
    return camera.render_enu(np.array([ne[1], ne[0], height]))


def test_a_polygons_slanted_edges_are_read_across_themselves_to_centimetres(polygon_scene) -> None:
    field, _, frame = polygon_scene
    field.set_targets(np.array([[4.0, 4.0], [5.0, 3.0]]))
    ring = frame.ned_to_grid(RING_NE)
    normals = ring_normals(ring)
    rng = np.random.default_rng(11)
    errors, in_view, seen_in_view = [], 0, 0
    for _ in range(30):
        i = int(rng.integers(len(ring)))
        a, b = ring[i], ring[(i + 1) % len(ring)]
        truth = a + (b - a) * rng.uniform(0.25, 0.75) - normals[i] * rng.uniform(0.5, 3.5)
        height = float(rng.uniform(3.0, 4.0))
        believed = truth + rng.normal(0.0, 0.8, 2)  # the GPS bias the edge corrects
        seen = find_ring_edges(_polygon_frame(polygon_scene, truth, height), height, ring, believed)
        for e in seen:
            assert np.allclose(e.normal_ne, normals[e.edge])
            errors.append(e.offset_m - float(normals[e.edge] @ (ring[e.edge] - truth)))
        if normals[i] @ (a - truth) < half_footprint_m(height) - 0.5:
            in_view += 1
            seen_in_view += i in {e.edge for e in seen}
    errors = np.array(errors)
    assert in_view >= 25 and seen_in_view == in_view
    assert abs(errors.mean()) < 0.02 and np.abs(errors).max() < 0.05
    # mid-field: no edge in view, none read
    assert find_ring_edges(_polygon_frame(polygon_scene, np.array([4.0, -8.0]), 3.5), 3.5, ring,
                           np.array([4.0, -8.0])) == []


def test_ring_normals_point_out_of_the_field_either_way_round() -> None:
    ring = np.array([[0.0, 0.0], [0.0, 10.0], [-10.0, 10.0], [-10.0, 0.0]])  # north, east
    out = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    np.testing.assert_allclose(ring_normals(ring), out, atol=1e-12)
    np.testing.assert_allclose(ring_normals(ring[::-1]), np.roll(out[::-1], -1, axis=0), atol=1e-12)
