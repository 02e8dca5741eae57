"""Readers for the files operators draw fields in: QGroundControl `.plan`, KML / KMZ, GeoJSON.
The format is told by the file's suffix; each reader uses the standard library only."""

from __future__ import annotations

from pathlib import Path

from ..errors import FieldError
from ..shapes import Shapes
from .geojson import read_geojson
from .kml import read_kml
from .qgc import read_plan

#: suffix -> reader; what `uavsearch field` accepts
FORMATS = {".plan": "QGroundControl plan", ".kml": "KML", ".kmz": "KMZ (zipped KML)",
           ".geojson": "GeoJSON", ".json": "GeoJSON"}


def read_shapes(path: str | Path) -> Shapes:
    """The field and no-fly polygons a file draws, or a FieldError naming the file."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".plan":
        return read_plan(p)
    if suffix in (".kml", ".kmz"):
        return read_kml(p, suffix[1:])
    if suffix in (".geojson", ".json"):
        return read_geojson(p)
    raise FieldError(p, f"unknown field format {suffix or '(no suffix)'!r}; accepted: "
                        + ", ".join(f"{s} ({n})" for s, n in FORMATS.items()))


__all__ = ["FORMATS", "read_shapes", "read_geojson", "read_kml", "read_plan"]
