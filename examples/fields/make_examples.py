"""How the three example fields were drawn: shapes in metres about the project's default home
(51.4545, -2.5879, the SITL's default), turned into the files an operator would export, with
vertices rounded to 1e-7 degrees (~1 cm) as QGroundControl and Google Earth write them.

    python examples/fields/make_examples.py     # rewrites the three files beside it

Each field holds home on a searchable cell, so the SITL's default vehicle starts inside it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from sim.gridworld.geodesy import HomePosition

HOME = HomePosition()  # 51.4545, -2.5879, 30 m AMSL
HERE = Path(__file__).resolve().parent


def latlon(ne: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out = []
    for n, e in ne:
        la, lo, _ = HOME.ned_to_geodetic(np.array([n, e, 0.0]))
        out.append((round(la, 7), round(lo, 7)))
    return out


def along(bearing_deg: float, pts: list[tuple[float, float]], at: tuple[float, float] = (0.0, 0.0)):
    """(a, b) metres along bearing and bearing + 90 -> (north, east), shifted by `at`."""
    h = math.radians(bearing_deg)
    return [(at[0] + a * math.cos(h) - b * math.sin(h), at[1] + a * math.sin(h) + b * math.cos(h)) for a, b in pts]


def paddock_geojson() -> dict:
    """An L-shaped paddock whose arms run at 30 and 120 degrees: 48 m x 50 m with a
    22 m x 20 m corner taken out (1960 m^2)."""
    ring = along(30.0, [(0, 0), (48, 0), (48, 30), (26, 30), (26, 50), (0, 50)], at=(-4.4, -16.4))
    ll = latlon(ring)
    coords = [[lo, la] for la, lo in ll] + [[ll[0][1], ll[0][0]]]
    return {"type": "FeatureCollection", "features": [{
        "type": "Feature", "properties": {"name": "L paddock"},
        "geometry": {"type": "Polygon", "coordinates": [coords]}}]}


def pond_kml() -> str:
    """A four-sided meadow (about 52 m x 46 m, 2300 m^2) with a pond of 7 m radius near its
    north-east corner drawn as a 14-gon inner ring."""
    outer = latlon([(-22, -26), (-20, 27), (24, 25), (25, -24)])
    pond = latlon([(12 + 7 * math.cos(t), 12 + 7 * math.sin(t))
                   for t in np.arange(14) * (2 * math.pi / 14)][::-1])

    def coords(vs: list[tuple[float, float]]) -> str:
        return " ".join(f"{lo},{la},0" for la, lo in vs + vs[:1])

    return f"""<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2" xmlns:gx="http://www.google.com/kml/ext/2.2">
<Document>
\t<name>Pond meadow.kml</name>
\t<Style id="field"><LineStyle><color>ff00aa00</color><width>2</width></LineStyle><PolyStyle><color>4000aa00</color></PolyStyle></Style>
\t<Placemark>
\t\t<name>Pond meadow</name>
\t\t<styleUrl>#field</styleUrl>
\t\t<Polygon>
\t\t\t<tessellate>1</tessellate>
\t\t\t<outerBoundaryIs><LinearRing><coordinates>
\t\t\t\t{coords(outer)}
\t\t\t</coordinates></LinearRing></outerBoundaryIs>
\t\t\t<innerBoundaryIs><LinearRing><coordinates>
\t\t\t\t{coords(pond)}
\t\t\t</coordinates></LinearRing></innerBoundaryIs>
\t\t</Polygon>
\t</Placemark>
</Document>
</kml>
"""


def farm_plan() -> dict:
    """A farmyard paddock as an inclusion geofence (a pentagon, about 2000 m^2) with the barn
    (14 m x 8 m, its long side at 75 degrees) as an exclusion polygon, and a take-off / RTL
    mission from home, as QGroundControl 4 saves it."""
    fence = latlon([(-23, -21), (-25, 19), (6, 29), (26, 8), (17, -24)])
    barn = latlon(along(75.0, [(0, 0), (14, 0), (14, 8), (0, 8)], at=(10.0, -19.0)))
    items = [
        {"AMSLAltAboveTerrain": None, "Altitude": 10, "AltitudeMode": 1, "autoContinue": True, "command": 22,
         "doJumpId": 1, "frame": 3, "params": [0, 0, 0, None, HOME.lat_deg, HOME.lon_deg, 10], "type": "SimpleItem"},
        {"autoContinue": True, "command": 20, "doJumpId": 2, "frame": 2, "params": [0, 0, 0, 0, 0, 0, 0],
         "type": "SimpleItem"},
    ]
    return {
        "fileType": "Plan",
        "geoFence": {"circles": [], "polygons": [
            {"inclusion": True, "polygon": [list(v) for v in fence], "version": 1},
            {"inclusion": False, "polygon": [list(v) for v in barn], "version": 1}], "version": 2},
        "groundStation": "QGroundControl",
        "mission": {"cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1, "hoverSpeed": 5,
                    "items": items, "plannedHomePosition": [HOME.lat_deg, HOME.lon_deg, HOME.alt_m],
                    "vehicleType": 2, "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "version": 1,
    }


def main() -> None:
    (HERE / "l_paddock_30deg.geojson").write_text(json.dumps(paddock_geojson(), indent=2) + "\n")
    (HERE / "pond_meadow.kml").write_text(pond_kml())
    (HERE / "farm_barn.plan").write_text(json.dumps(farm_plan(), indent=4) + "\n")


if __name__ == "__main__":
    main()
