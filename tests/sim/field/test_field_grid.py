"""The grid over a polygon: heading 0 is today's mapping, rotated frames round-trip, the
default heading, the mask's classes, field.json back to the same object."""

import json
from pathlib import Path

import numpy as np
import pytest

from sim.field import FORBIDDEN, OUTSIDE, SEARCHABLE, FieldError, GridFrame, load_field, write_field
from sim.field.model import build_field
from sim.field.shapes import Area, Ring, Shapes
from sim.gridworld import cell_to_ned, nearest_cell, ned_to_cell
from sim.gridworld.geodesy import HomePosition

HOME = HomePosition()


def shapes(outer_ne: list, holes_ne: tuple = (), exclusions_ne: tuple = ()) -> Shapes:
    def ring(label: str, ne: list) -> Ring:
        return Ring(label, tuple(HOME.ned_to_geodetic(np.array([n, e, 0.0]))[:2] for n, e in ne))

    return Shapes(Area("field", ring("outer", outer_ne), tuple(ring(f"hole {i}", h) for i, h in enumerate(holes_ne))),
                  tuple(Area(f"ex {i}", ring(f"ex {i}", x)) for i, x in enumerate(exclusions_ne)), "test")


def test_heading_zero_is_todays_mapping_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    cells = np.concatenate([rng.integers(0, 40, size=(200, 2)), rng.uniform(-3, 40, size=(200, 2))])
    ne = rng.uniform(-100, 100, size=(300, 2))
    for cell_m in (2.0, 3.5):
        f = GridFrame(0.0, cell_m)
        assert f.cell_to_ned(cells).tobytes() == cell_to_ned(cells, cell_m).tobytes()
        assert f.ned_to_cell(ne).tobytes() == ned_to_cell(ne, cell_m).tobytes()
        assert np.array_equal(f.nearest_cell(ne), nearest_cell(ne, cell_m))
    assert GridFrame().cell_to_ned((3, 4)).tolist() == [-8.0, 6.0]


@pytest.mark.parametrize("heading", [30.0, -17.25, 123.0, 271.5])
def test_rotated_frame_round_trip_and_axes(heading: float) -> None:
    f = GridFrame(heading, 2.0, (12.5, -7.25))
    rng = np.random.default_rng(1)
    cells = rng.uniform(-5, 30, size=(500, 2))
    np.testing.assert_allclose(f.ned_to_cell(f.cell_to_ned(cells)), cells, atol=1e-12)
    ne = rng.uniform(-80, 80, size=(500, 2))
    np.testing.assert_allclose(f.cell_to_ned(f.ned_to_cell(ne)), ne, atol=1e-12)
    assert np.array_equal(f.nearest_cell(f.cell_to_ned(np.array([[4, 9]]))), [[4, 9]])
    o = f.cell_to_ned((0, 0))
    assert o.tolist() == [12.5, -7.25]
    h = np.radians(heading)
    np.testing.assert_allclose(f.cell_to_ned((0, -1)) - o, 2 * np.array([np.cos(h), np.sin(h)]), atol=1e-12)  # f
    np.testing.assert_allclose(f.cell_to_ned((1, 0)) - o, 2 * np.array([-np.sin(h), np.cos(h)]), atol=1e-12)  # r


def _rect(bearing: float, a: float, b: float) -> list:
    h = np.radians(bearing)
    return [(x * np.cos(h) - y * np.sin(h), x * np.sin(h) + y * np.cos(h)) for x, y in [(0, 0), (a, 0), (a, b), (0, b)]]


def test_default_heading_is_the_minimum_rectangles_nearest_north() -> None:
    assert build_field(shapes(_rect(30.0, 40, 24)), "t").heading_deg == pytest.approx(30.0, abs=2e-4)
    assert build_field(shapes(_rect(60.0, 40, 24)), "t").heading_deg == pytest.approx(-30.0, abs=2e-4)
    f = build_field(shapes(_rect(0.0, 20, 16)), "t")
    assert f.heading_deg == 0.0 and (f.width, f.height) == (8, 10) and f.searchable_cells == 80
    assert build_field(shapes(_rect(30.0, 40, 24)), "t", heading_deg=390.0).heading_deg == 30.0
    g = build_field(shapes(_rect(30.0, 40, 24)), "t")
    assert (g.width, g.height) == (12, 20) and g.searchable_cells == 240  # the rectangle, cell for cell


def test_mask_classes_on_a_polygon_with_a_hole_and_an_exclusion() -> None:
    # 20 m x 20 m north-aligned: 10 x 10 cells on the cell lines; x east, y south from the NW corner
    square = [(0, 0), (0, 20), (20, 20), (20, 0)]
    hole = [(8, 8), (8, 12), (12, 12.2), (12, 8)]  # reaches 0.2 m into the cells east of x = 12 m
    barn = [(18.5, 1), (25, 1), (25, 3), (18.5, 3)]  # crosses the north edge: its inside part counts
    f = build_field(shapes(square, (hole,), (barn,)), "t")
    assert (f.width, f.height, f.heading_deg) == (10, 10, 0.0)
    c = f.classes
    forbidden = {(int(x), int(y)) for y, x in np.argwhere(c == FORBIDDEN)}
    # hole: rows north 8..12 -> y 4, 5; columns east 8..12 -> x 4, 5, and x 6 where it reaches in
    assert {(4, 4), (5, 4), (4, 5), (5, 5)} <= forbidden and (6, 4) in forbidden
    assert (3, 4) not in forbidden and (4, 3) not in forbidden  # touching along an edge is not sharing
    assert {(0, 0), (1, 0)} <= forbidden  # the barn's part inside the field: north 18.5..20, east 1..3
    assert len(forbidden) == 8 and (OUTSIDE not in c)
    assert f.mask.dtype == bool and f.mask.sum() == 92 == f.searchable_cells
    with pytest.raises(ValueError):
        f.mask[0, 0] = True  # the product is read-only
    # an L: the notch's cells are outside, and never searchable
    el = build_field(shapes([(0, 0), (0, 20), (10, 20), (10, 10), (20, 10), (20, 0)]), "t")
    assert (el.classes[:5, 5:] == OUTSIDE).all() and (el.classes[5:, :] == SEARCHABLE).all()


def test_field_json_round_trip_and_tampering(tmp_path: Path) -> None:
    f = build_field(shapes(_rect(30.0, 40, 24), (), (_rect(30.0, 6, 6),)), "t")
    write_field(tmp_path / "field.json", f, {"cell_m": 2.0})
    g = load_field(tmp_path / "field.json")
    assert np.array_equal(f.classes, g.classes) and g.origin == f.origin and g.heading_deg == f.heading_deg
    assert g.outer == f.outer and g.no_fly == f.no_fly
    lat, lon = g.cell_to_latlon((0, 0))
    assert (lat, lon) == pytest.approx((f.origin.lat_deg, f.origin.lon_deg), abs=1e-12)
    d = json.loads((tmp_path / "field.json").read_text())
    assert d["provenance"]["config"] == {"cell_m": 2.0} and d["searchable_cells"] == f.searchable_cells
    row = d["mask"][5]
    d["mask"][5] = ("x" if row[5] == "s" else "s").join([row[:5], row[6:]])
    d["searchable_cells"] = sum(r.count("s") for r in d["mask"])
    (tmp_path / "edited.json").write_text(json.dumps(d))
    with pytest.raises(FieldError, match=r"edited.json: the mask does not match its polygons \(1 cell"):
        load_field(tmp_path / "edited.json")
    (tmp_path / "sitl.json").write_text(json.dumps({"kind": "uavsearch field"}))
    with pytest.raises(FieldError, match="that is the SITL's field file"):
        load_field(tmp_path / "sitl.json")
    d = json.loads((tmp_path / "field.json").read_text())
    d["width"] = 3
    (tmp_path / "w.json").write_text(json.dumps(d))
    with pytest.raises(FieldError, match=r"mask must be \d+ rows of 3 characters"):
        load_field(tmp_path / "w.json")


@pytest.mark.parametrize("name", ["l_paddock_30deg.geojson", "pond_meadow.kml", "farm_barn.plan"])
def test_examples_searchable_centres_allowed_and_moves_never_cross_a_no_fly_zone(name: str) -> None:
    import shapely

    from sim.field import read_field_file

    f = read_field_file(str(Path(__file__).resolve().parents[3] / "examples" / "fields" / name))
    committed = load_field(Path(__file__).resolve().parents[3] / "examples" / "fields" / "out" / name.split(".")[0]
                           / "field.json")  # what the command wrote is what it makes today
    assert np.array_equal(committed.classes, f.classes) and committed.origin == f.origin
    if name.startswith("l_paddock"):  # drawn to 1 cm: its sides still fall on cell lines
        assert (f.width, f.height, f.searchable_cells) == (25, 24, 1960 // 4)
    ys, xs = np.nonzero(f.mask)
    centres = f.cell_to_ned(np.stack([xs, ys], axis=-1).astype(float))
    assert f.allowed(centres).all()
    blocked = shapely.union_all([shapely.Polygon(r[:, ::-1]) for r in f.rings_ne()[1]]) if f.no_fly else None
    for dx, dy in ((1, 0), (0, 1)):  # every move between two neighbouring searchable cells
        a = f.mask[: f.height - dy, : f.width - dx] & f.mask[dy:, dx:]
        y0, x0 = np.nonzero(a)
        p = f.cell_to_ned(np.stack([x0, y0], -1).astype(float))[..., ::-1]
        q = f.cell_to_ned(np.stack([x0 + dx, y0 + dy], -1).astype(float))[..., ::-1]
        if blocked is not None:
            assert not shapely.intersects(shapely.linestrings(np.stack([p, q], axis=1)), blocked).any()
