"""KML (OGC KML 2.2, as Google Earth and QGroundControl write it) and KMZ (its zip).

Every Polygon in the document, in a Placemark or a MultiGeometry: outerBoundaryIs is the
outer ring, each innerBoundaryIs a hole. Coordinates are `lon,lat[,alt]` tuples on WGS84 (KML
has no other CRS); altitudes are ignored. KML says a ring repeats its first vertex at its
end, but QGroundControl reads rings that do not, so an open ring is closed here rather than
refused. With several polygons, the largest is the field and the others no-fly zones."""

from __future__ import annotations

import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from ..errors import FieldError
from ..shapes import Area, Ring, Shapes
from .common import no_holes_in_exclusion, pick_field, ring, vertex

ORDER = "lon, lat"


def _local(tag: object) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _children(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el if _local(c.tag) == name]


def _descendants(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el.iter() if _local(c.tag) == name]


def _text(path: Path, kind: str) -> bytes:
    try:
        if kind == "kmz":
            with zipfile.ZipFile(path) as z:
                names = [n for n in z.namelist() if n.lower().endswith(".kml")]
                if not names:
                    raise FieldError(path, "is a KMZ without a .kml inside")
                name = "doc.kml" if "doc.kml" in names else names[0]
                return z.read(name)
        return path.read_bytes()
    except FileNotFoundError:
        raise FieldError(path, "no such file") from None
    except IsADirectoryError:
        raise FieldError(path, "is a directory, not a field file") from None
    except zipfile.BadZipFile:
        raise FieldError(path, "is not a KMZ (not a zip archive)") from None
    except OSError as e:
        raise FieldError(path, f"cannot be read ({e.strerror})") from None


def read_kml(path: Path, kind: str = "kml") -> Shapes:
    data = _text(path, kind)
    if not data.strip():
        raise FieldError(path, "is empty (a KML file is XML)")
    try:
        root = ET.fromstring(data)
    except ET.ParseError as e:
        line, col = e.position
        raise FieldError(path, f"is not well-formed XML (line {line}, column {col})") from None
    except LookupError as e:  # <?xml encoding="..."?> naming no codec
        raise FieldError(path, f"declares an unknown text encoding ({e})") from None
    if _local(root.tag) != "kml":
        raise FieldError(path, f"is not KML: its root element is <{_local(root.tag)}>, not <kml>")
    areas: list[Area] = []
    seen: set[int] = set()
    for pi, pm in enumerate(_descendants(root, "Placemark")):
        names = _children(pm, "name")
        pname = (names[0].text or "").strip() if names else ""
        where = f"Placemark {pname!r}" if pname else f"Placemark {pi}"
        polys = _descendants(pm, "Polygon")
        for k, poly in enumerate(polys):
            seen.add(id(poly))
            label = where if len(polys) == 1 else f"{where} polygon {k}"
            areas.append(_polygon(path, poly, label, pname or None))
    for k, poly in enumerate(p for p in _descendants(root, "Polygon") if id(p) not in seen):
        areas.append(_polygon(path, poly, f"Polygon {k} (outside any Placemark)", None))
    if not areas:
        counts = {t: len(_descendants(root, t)) for t in ("Point", "LineString", "LinearRing", "Model")}
        held = ", ".join(f"{n} {t}(s)" for t, n in counts.items() if n) or "no geometry"
        raise FieldError(path, f"no polygon found (it holds {held}); a field is a <Polygon>")
    field, rest = pick_field(path, areas, [], "")
    for a in rest:
        no_holes_in_exclusion(path, a)
    src = f"KML: {field.label}" + (f" (the largest of {len(areas)} polygons; the others are no-fly)"
                                   if len(areas) > 1 else "")
    return Shapes(field, tuple(rest), src, None)


def _polygon(path: Path, poly: ET.Element, label: str, name: str | None) -> Area:
    outer = _children(poly, "outerBoundaryIs")
    if len(outer) != 1:
        raise FieldError(path, f"{label}: a <Polygon> needs exactly one <outerBoundaryIs> (found {len(outer)})")
    o = _boundary(path, outer[0], f"{label} outer ring")
    if len(o) != 1:
        raise FieldError(path, f"{label}: <outerBoundaryIs> needs one <LinearRing> (found {len(o)})")
    holes: list[Ring] = []
    for ib in _children(poly, "innerBoundaryIs"):
        for r in _boundary(path, ib, f"{label} inner ring {len(holes)}"):
            holes.append(Ring(f"{label} inner ring {len(holes)} (a hole)", r.vertices))
    return Area(label, o[0], tuple(holes), name)


def _boundary(path: Path, b: ET.Element, label: str) -> list[Ring]:
    out = []
    for lr in _children(b, "LinearRing"):
        cs = _children(lr, "coordinates")
        if len(cs) != 1:
            raise FieldError(path, f"{label}: a <LinearRing> needs one <coordinates>")
        out.append(_coordinates(path, cs[0].text or "", label))
    return out


def _coordinates(path: Path, text: str, label: str) -> Ring:
    # tuples are separated by whitespace; some writers put a space after the commas
    tuples = ",".join(p.strip() for p in text.split(",")).split()
    vs = []
    for t in tuples:
        parts = t.split(",")
        try:
            nums = [float(p) for p in parts]
        except ValueError:
            raise FieldError(path, f"{label}: coordinate {t[:40]!r} is not lon,lat[,alt]") from None
        if len(nums) not in (2, 3):
            raise FieldError(path, f"{label}: coordinate {t[:40]!r} is not lon,lat[,alt]")
        vs.append(vertex(path, label, nums[1], nums[0], ORDER))
    return ring(path, label, vs)
