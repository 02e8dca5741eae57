"""Each reader on the committed examples, and on bad files: one line naming the file."""

import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

from sim.field import FieldError, read_field_file, read_shapes
from sim.gridworld.geodesy import HomePosition

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "fields"
HOME = HomePosition()


def ll(ne: list[tuple[float, float]]) -> list[tuple[float, float]]:
    return [HOME.ned_to_geodetic(np.array([n, e, 0.0]))[:2] for n, e in ne]


def ring_lonlat(ne: list[tuple[float, float]], close: bool = True) -> list[list[float]]:
    r = [[lo, la] for la, lo in ll(ne)]
    return r + r[:1] if close else r


SQUARE = [(0, 0), (0, 30), (30, 30), (30, 0)]


def geojson(*rings: list[list[float]], **extra: object) -> str:
    return json.dumps({"type": "Polygon", "coordinates": list(rings), **extra})


def test_examples_read() -> None:
    g = read_shapes(EXAMPLES / "l_paddock_30deg.geojson")
    assert len(g.field.outer.vertices) == 6 and not g.field.holes and not g.exclusions
    assert "L paddock" in g.source
    k = read_shapes(EXAMPLES / "pond_meadow.kml")
    assert len(k.field.outer.vertices) == 4 and len(k.field.holes) == 1 and len(k.field.holes[0].vertices) == 14
    p = read_shapes(EXAMPLES / "farm_barn.plan")
    assert len(p.field.outer.vertices) == 5 and len(p.exclusions) == 1 and p.alt_m == 30.0
    assert "inclusion polygon" in p.source
    for shapes in (g, k, p):  # near the project's default home
        la, lo = shapes.field.outer.vertices[0]
        assert abs(la - HOME.lat_deg) < 1e-3 and abs(lo - HOME.lon_deg) < 1e-3


BAD = [
    ("empty.geojson", "", "is empty"),
    ("trunc.geojson", '{"type": "Polygon", "coordinates": [[', "is not valid JSON (line 1"),
    ("point.geojson", json.dumps({"type": "Point", "coordinates": [-2.5879, 51.4545]}),
     "no field polygon found (it holds 1 Point(s))"),
    ("list.geojson", "[1, 2]", "is not GeoJSON"),
    ("open.geojson", geojson(ring_lonlat(SQUARE, close=False)), "is not closed"),
    ("two.geojson", geojson(ring_lonlat([(0, 0), (0, 30), (0, 0)], close=False) + ring_lonlat([(0, 0)])),
     "a polygon needs at least 3"),
    ("bowtie.geojson", geojson(ring_lonlat([(0, 0), (30, 30), (30, 0), (0, 30)])), "crosses itself near 51.45"),
    ("line.geojson", geojson(ring_lonlat([(0, 0), (10, 10), (20, 20)])), "encloses no area"),
    ("bng.geojson", geojson(ring_lonlat(SQUARE), crs={"type": "name", "properties": {"name": "EPSG:27700"}}),
     "CRS 'EPSG:27700' is not WGS84"),
    ("huge.geojson", geojson(ring_lonlat([(0, 0), (0, 40000), (300, 40000), (300, 0)])),
     "the field spans 300 m north-south x 40.0 km east-west; the limit is 1000 m"),
    ("cells.geojson", geojson(ring_lonlat([(0, 0), (0, 300), (300, 300), (300, 0)])),
     "the grid is 150 x 150 = 22500 cells of 2 m, over the limit of 10000 cells; use a larger --cell-m (about 3)"),
    # Adelaide written [lat, lon]: a longitude of -34.9 and a latitude of 138.6
    ("swapped.geojson", geojson([[-34.9285, 138.6007], [-34.9285, 138.6010], [-34.9282, 138.6010],
                                 [-34.9285, 138.6007]]),
     "out of range (the file's order is lon, lat: are they swapped?)"),
    ("metres.geojson", geojson([[358000.0, 172000.0], [358030.0, 172000.0], [358030.0, 172030.0],
                                [358000.0, 172000.0]]), "is not in degrees: projected coordinates?"),
    ("hole.geojson", geojson(ring_lonlat(SQUARE), ring_lonlat([(40, 40), (40, 45), (45, 45), (45, 40)])),
     "a hole lies outside it"),
    ("covered.geojson", json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": json.loads(geojson(ring_lonlat(SQUARE)))},
        {"type": "Feature", "properties": {"inclusion": False},
         "geometry": json.loads(geojson(ring_lonlat([(-1, -1), (-1, 31), (31, 31), (31, -1)])))}]}),
     "no cell of the 15 x 15 grid is searchable"),
    ("bad.kml", "<kml><Document>", "is not well-formed XML (line 1"),
    ("enc.kml", '<?xml version="1.0" encoding="UTF-x8"?><kml/>', "declares an unknown text encoding"),
    ("html.kml", "<html><body/></html>", "is not KML: its root element is <html>"),
    ("pin.kml", '<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><Point><coordinates>-2.5879,51.4545'
                "</coordinates></Point></Placemark></kml>", "no polygon found (it holds 1 Point(s))"),
    ("words.kml", "<kml><Placemark><Polygon><outerBoundaryIs><LinearRing><coordinates>a,b c,d e,f"
                  "</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark></kml>",
     "Placemark 0 outer ring: coordinate 'a,b' is not lon,lat[,alt]"),
    ("mission.plan", json.dumps({"fileType": "Mission"}), "is not a QGroundControl plan (fileType 'Mission'"),
    ("circle.plan", json.dumps({"fileType": "Plan", "geoFence": {"circles": [
        {"inclusion": True, "circle": {"center": [51.4545, -2.5879], "radius": 50}, "version": 1}],
        "polygons": [], "version": 2}, "mission": {"items": []}}), "no polygon found (1 inclusion circle(s)"),
    ("twice.plan", json.dumps({"fileType": "Plan", "geoFence": {"polygons": [
        {"inclusion": True, "polygon": [list(v) for v in ll(SQUARE)]},
        {"inclusion": True, "polygon": [list(v) for v in ll([(50, 50), (50, 60), (60, 60)])]}]}}),
     "has 2 inclusion polygons; a field is one"),
    ("field.shp", "x", "unknown field format '.shp'"),
]


@pytest.mark.parametrize(("name", "text", "says"), BAD, ids=[b[0] for b in BAD])
def test_bad_files_get_one_line_naming_the_file(tmp_path: Path, name: str, text: str, says: str) -> None:
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(FieldError) as e:
        read_field_file(str(p))
    msg = str(e.value)
    assert msg.startswith(f"{p}: ") and "\n" not in msg
    assert says in msg, msg


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(FieldError, match="no such file"):
        read_shapes(tmp_path / "nope.kml")
    (tmp_path / "d.geojson").mkdir()
    with pytest.raises(FieldError, match="is a directory"):
        read_shapes(tmp_path / "d.geojson")


def test_geojson_several_polygons_largest_is_field_and_inclusion_false_is_no_fly(tmp_path: Path) -> None:
    feats = [
        {"type": "Feature", "properties": {"name": "shed", "inclusion": False},
         "geometry": {"type": "Polygon", "coordinates": [ring_lonlat([(2, 2), (2, 6), (6, 6), (6, 2)])]}},
        {"type": "Feature", "properties": {"name": "trees"}, "geometry": {"type": "MultiPolygon", "coordinates": [
            [ring_lonlat(SQUARE)], [ring_lonlat([(20, 20), (20, 24), (24, 24), (24, 20)])]]}},
    ]
    p = tmp_path / "f.geojson"
    p.write_text(json.dumps({"type": "FeatureCollection", "crs": {"type": "name", "properties": {
        "name": "urn:ogc:def:crs:OGC:1.3:CRS84"}}, "features": feats}))
    s = read_shapes(p)
    assert s.field.label == "feature 1 ('trees') polygon 0"
    assert sorted(a.name for a in s.exclusions) == ["shed", "trees"]
    f = read_field_file(str(p))
    assert f.counts()["forbidden"] == 8  # two 4 m squares on the 2 m cell lines: 2 x 2 cells each


def test_plan_survey_polygon_and_exclusion_circle(tmp_path: Path) -> None:
    plan = {"fileType": "Plan", "geoFence": {"circles": [
        {"inclusion": False, "circle": {"center": list(ll([(15, 15)])[0]), "radius": 3}, "version": 1}],
        "polygons": [], "version": 2},
        "mission": {"items": [{"type": "ComplexItem", "complexItemType": "survey",
                               "polygon": [list(v) for v in ll(SQUARE)]}]}}
    p = tmp_path / "s.plan"
    p.write_text(json.dumps(plan))
    s = read_shapes(p)
    assert "Survey polygon" in s.source and len(s.exclusions) == 1
    f = read_field_file(str(p))
    outer, (circle,) = f.rings_ne()
    centre = HOME.geodetic_to_ned(*ll([(15, 15)])[0], HOME.alt_m)[:2] - \
        HOME.geodetic_to_ned(f.origin.lat_deg, f.origin.lon_deg, HOME.alt_m)[:2]
    d = np.hypot(*(circle - centre).T)
    assert len(circle) == 36 and np.all(d >= 3.0 - 1e-3) and np.all(d <= 3.0 / math.cos(math.pi / 36) + 1e-3)
    assert f.counts()["forbidden"] >= 9  # a 6 m wide circle on 2 m cells


def test_kmz_and_open_kml_ring(tmp_path: Path) -> None:
    coords = " ".join(f"{lo},{la}" for la, lo in ll(SQUARE))  # not closed: QGC reads these, so do we
    kml = ("<?xml version='1.0'?><kml xmlns='http://www.opengis.net/kml/2.2'><Document><Placemark>"
           f"<name>yard</name><MultiGeometry><Polygon><outerBoundaryIs><LinearRing><coordinates>{coords}"
           "</coordinates></LinearRing></outerBoundaryIs></Polygon></MultiGeometry></Placemark></Document></kml>")
    with zipfile.ZipFile(tmp_path / "y.kmz", "w") as z:
        z.writestr("doc.kml", kml)
    s = read_shapes(tmp_path / "y.kmz")
    assert s.field.name == "yard" and len(s.field.outer.vertices) == 4
    (tmp_path / "z.kmz").write_text("not a zip")
    with pytest.raises(FieldError, match="is not a KMZ"):
        read_shapes(tmp_path / "z.kmz")
