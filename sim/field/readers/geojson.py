"""GeoJSON (RFC 7946): a Polygon, a MultiPolygon, a Feature or a FeatureCollection of them.

Positions are [lon, lat(, alt)] on WGS84; RFC 7946 removed the "crs" member, and a file that
still carries one naming anything but WGS84 (British National Grid, Web Mercator) would put
the field kilometres off, so it is refused. The first ring of a Polygon is the field's outer
ring, the others its holes. With several polygons, a Feature whose properties say
`"inclusion": false` (QGroundControl's word) is a no-fly zone; of the rest the largest is the
field and the others no-fly zones."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from provenance import InputFileError, read_json

from ..errors import FieldError
from ..shapes import Area, Shapes
from .common import no_holes_in_exclusion, pick_field, ring, vertex

#: "crs" names that mean WGS84 longitude/latitude (GeoJSON 2008 and what tools write)
WGS84_NAMES = frozenset({
    "urn:ogc:def:crs:ogc:1.3:crs84", "urn:ogc:def:crs:ogc::crs84", "crs84", "ogc:crs84",
    "epsg:4326", "urn:ogc:def:crs:epsg::4326", "urn:ogc:def:crs:epsg:6.6:4326", "wgs84",
    "http://www.opengis.net/def/crs/ogc/1.3/crs84", "http://www.opengis.net/def/crs/epsg/0/4326",
})
ORDER = "lon, lat"


def load_json(path: Path, what: str) -> Any:
    """The file's JSON, or one line saying why not."""
    try:
        return read_json(path, f"{what} file")
    except InputFileError as e:
        raise FieldError(path, e.what) from None


def read_geojson(path: Path) -> Shapes:
    doc = load_json(path, "GeoJSON")
    if not isinstance(doc, dict) or not isinstance(doc.get("type"), str):
        raise FieldError(path, "is not GeoJSON: the top level must be an object with a \"type\"")
    _check_crs(path, doc)
    fields: list[Area] = []
    exclusions: list[Area] = []
    others: dict[str, int] = {}
    t = doc["type"]
    if t == "FeatureCollection":
        feats = doc.get("features")
        if not isinstance(feats, list):
            raise FieldError(path, "FeatureCollection has no \"features\" list")
        for i, f in enumerate(feats):
            _feature(path, f, f"feature {i}", fields, exclusions, others)
    elif t == "Feature":
        _feature(path, doc, "the Feature", fields, exclusions, others)
    else:
        _geometry(path, doc, "the geometry", None, fields, others)
    what = ", ".join(f"{n} {k}" for k, n in others.items()) or "nothing"
    if not fields and exclusions:
        raise FieldError(path, f"no field polygon found: every polygon says \"inclusion\": false ({what} else)")
    field, rest = pick_field(path, fields, exclusions, f"it holds {what}")
    for a in rest:
        no_holes_in_exclusion(path, a)
    n = len(fields) + len(exclusions)
    src = f"GeoJSON {t}: {field.label}" + \
          (f" (the largest of {n} polygons; the others are no-fly)" if n > 1 else "")
    return Shapes(field, tuple(rest), src, None)


def _check_crs(path: Path, obj: dict[str, Any]) -> None:
    crs = obj.get("crs")
    if crs is None:
        return
    name = None
    if isinstance(crs, dict):
        props = crs.get("properties")
        if crs.get("type") == "name" and isinstance(props, dict):
            name = props.get("name")
        elif crs.get("type") == "EPSG" and isinstance(props, dict):  # GeoJSON 2008 drafts
            name = f"EPSG:{props.get('code')}"
    if not isinstance(name, str):
        raise FieldError(path, f"has a \"crs\" member that names no CRS ({json.dumps(crs)[:80]}); RFC 7946 "
                               f"GeoJSON is WGS84 longitude/latitude: remove it or reproject to EPSG:4326")
    if name.strip().lower() not in WGS84_NAMES:
        raise FieldError(path, f"CRS {name!r} is not WGS84; RFC 7946 GeoJSON is WGS84 longitude/latitude: "
                               f"reproject it (e.g. ogr2ogr -t_srs EPSG:4326 out.geojson in.geojson)")


def _feature(path: Path, f: Any, label: str, fields: list[Area], exclusions: list[Area],
             others: dict[str, int]) -> None:
    if not isinstance(f, dict) or f.get("type") != "Feature":
        raise FieldError(path, f"{label} is not a GeoJSON Feature")
    _check_crs(path, f)
    props = f.get("properties") if isinstance(f.get("properties"), dict) else {}
    name = props.get("name") if isinstance(props.get("name"), str) else None
    if name:
        label = f"{label} ({name!r})"
    inclusion = props.get("inclusion", True)
    if not isinstance(inclusion, bool):
        raise FieldError(path, f"{label}: property \"inclusion\" must be true or false (got {inclusion!r})")
    geom = f.get("geometry")
    if geom is None:
        others["empty Feature(s)"] = others.get("empty Feature(s)", 0) + 1
        return
    _geometry(path, geom, label, name, exclusions if not inclusion else fields, others)


def _geometry(path: Path, g: Any, label: str, name: str | None, into: list[Area], others: dict[str, int]) -> None:
    if not isinstance(g, dict) or not isinstance(g.get("type"), str):
        raise FieldError(path, f"{label}: geometry is not a GeoJSON geometry object")
    t = g["type"]
    if t == "GeometryCollection":
        for i, sub in enumerate(g.get("geometries") or []):
            _geometry(path, sub, f"{label} geometry {i}", name, into, others)
        return
    if t not in ("Polygon", "MultiPolygon"):
        others[f"{t}(s)"] = others.get(f"{t}(s)", 0) + 1
        return
    coords = g.get("coordinates")
    polys = [coords] if t == "Polygon" else coords
    if not isinstance(polys, list):
        raise FieldError(path, f"{label}: {t} coordinates must be a list")
    for k, rings in enumerate(polys):
        plabel = label if t == "Polygon" else f"{label} polygon {k}"
        if not isinstance(rings, list) or not rings:
            raise FieldError(path, f"{plabel}: a Polygon's coordinates must be a list of rings")
        parsed = []
        for j, r in enumerate(rings):
            rl = f"{plabel} ring {j}" + (" (outer)" if j == 0 else " (a hole)")
            if not isinstance(r, list):
                raise FieldError(path, f"{rl} must be a list of positions")
            vs = []
            for p in r:
                if not isinstance(p, list) or len(p) < 2:
                    raise FieldError(path, f"{rl}: position {json.dumps(p)[:40]} is not [lon, lat]")
                vs.append(vertex(path, rl, p[1], p[0], ORDER))
            parsed.append(ring(path, rl, vs, closed_required=True))
        into.append(Area(plabel, parsed[0], tuple(parsed[1:]), name))
