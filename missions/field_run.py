"""A real field (`uavsearch field`'s field.json) flown by `uavsearch run` and `sitl`: which file
is one, and what of it the companion's spec takes (its grid, mask, heading and fence).

Its own module so `run`, `sitl` and the flight table build the same spec from a field, and
the command modules (which another change also edits) gain a line each, not a block."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from sim.gridworld import GridConfig

#: the `kind` of a field.json (sim.field.KIND); the SITL's own field file is "uavsearch field"
POLYGON_KIND = "uavsearch polygon field"


def is_polygon_file(path: Path) -> bool:
    """Whether `path` is a real field's field.json rather than the SITL's field file (False for
    anything unreadable: the SITL's reader then says what is wrong with it)."""
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(d, dict) and d.get("kind") == POLYGON_KIND


def load_polygon(path: Path):
    """The real field (`sim.field.PolygonField`), checked for flight: 2 m cells (the camera's)."""
    from sim.field import load_field

    pf = load_field(str(path))
    if pf.cell_m != 2.0:
        raise ValueError(f"{path}: its cells are {pf.cell_m:g} m; flights are built for 2 m cells "
                         "(uavsearch field --cell-m 2)")
    return pf


def on_polygon_grid(pf, grid: GridConfig) -> GridConfig:
    """`grid` on the field's grid (its width and height; targets, motion and the rest kept)."""
    return dataclasses.replace(grid, width=int(pf.width), height=int(pf.height))


def field_spec(pf) -> dict[str, Any]:
    """SearchSpec's entries for a real field: the area (heading, mask, edges) and the fence
    (its rings, with room for the autopilot's estimate: fence.FIELD_MARGIN_M)."""
    from autopilot_bridge.service.fence import FIELD_MARGIN_M, FencePlan
    from autopilot_bridge.service.field_area import FieldArea

    return {"area": FieldArea.of_field(pf), "fence": FencePlan.of_field(pf, FIELD_MARGIN_M)}
