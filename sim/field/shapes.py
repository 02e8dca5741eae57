"""What a reader hands on: the field's rings in WGS84 degrees, as the file drew them.

Readers only parse and check what a file can get wrong by itself (numbers, ranges, vertex
counts); geometry (crossing rings, holes outside the field, size) is checked in metres by
`sim.field.model.build_field`, with the same messages for every format."""

from __future__ import annotations

from dataclasses import dataclass

#: (lat, lon) degrees, WGS84; a ring's first vertex is not repeated at its end
LatLon = tuple[float, float]


@dataclass(frozen=True)
class Ring:
    #: where the ring is in its file, for messages ("Placemark 'Pond' outer ring")
    label: str
    vertices: tuple[LatLon, ...]


@dataclass(frozen=True)
class Area:
    """One polygon: an outer ring and its inner rings (holes)."""

    #: where the polygon is in its file ("feature 2 ('Barn')", "geoFence polygon 1")
    label: str
    outer: Ring
    holes: tuple[Ring, ...] = ()
    name: str | None = None


@dataclass(frozen=True)
class Shapes:
    """A file's field: the polygon to search and the no-fly polygons drawn beside it."""

    field: Area
    exclusions: tuple[Area, ...] = ()
    #: what the file held and which of it became the field ("geoFence inclusion polygon")
    source: str = ""
    #: the ground's altitude AMSL where the file gives one (a QGC plan's planned home), else None
    alt_m: float | None = None
