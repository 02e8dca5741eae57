"""Real fields: any polygon, at any heading, with holes and no-fly zones, from the files
operators draw them in (QGroundControl `.plan`, KML / KMZ, GeoJSON), gridded.

read_shapes(FILE) -> Shapes (WGS84 rings) -> build_field(...) -> PolygonField (the grid's
origin, heading, cell size and each cell's class; `mask` is the plain numpy array the grid
world takes) -> write_field / load_field (field.json). In sim/ because the SITL renders the
field; imports nothing from the other packages (numpy, shapely, sim.gridworld, provenance).
See docs/fields.md."""

from sim.gridworld.coords import DEFAULT_CELL_M

from .errors import FieldError
from .frame import GridFrame
from .grid import default_heading, lay_grid
from .mask import FORBIDDEN, OUTSIDE, SEARCHABLE, classify
from .model import KIND, MAX_CELLS, NoFly, PolygonField, build_field, load_field, write_field
from .projection import MAX_EXTENT_M, LocalProjection
from .readers import FORMATS, read_shapes
from .shapes import Area, Ring, Shapes


def read_field_file(path: str, cell_m: float = DEFAULT_CELL_M, heading_deg: float | None = None) -> PolygonField:
    """A polygon file (.plan, .kml, .kmz, .geojson) read and gridded in one call."""
    return build_field(read_shapes(path), path, cell_m, heading_deg)


__all__ = [
    "FieldError", "GridFrame", "default_heading", "lay_grid", "FORBIDDEN", "OUTSIDE", "SEARCHABLE",
    "classify", "KIND", "MAX_CELLS", "NoFly", "PolygonField", "build_field", "load_field", "write_field",
    "MAX_EXTENT_M", "LocalProjection", "FORMATS", "read_shapes", "Area", "Ring", "Shapes", "read_field_file",
]
