"""The field file: what `uavsearch sitl` tells `uavsearch run` about the field it simulates.

The companion needs the field's corner (cell (0, 0)'s centre, WGS84), its size, the cell size,
|R| and the target model, and where to connect; before this file an operator typed the origin
by hand and a wrong one flew 300 moves to find 1 of 5. It never holds the targets' positions
(the truth stays in the simulator). Written atomically with provenance."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from provenance import atomic_write_json, stamp
from sim.gridworld import DEFAULT_CELL_M, ConfigError, GridConfig
from sim.gridworld.geodesy import HomePosition

KIND = "uavsearch field"
DIALECTS = ("px4", "ardupilot")  # sim.mavlink.dialects.DIALECTS (missions reads no sim.mavlink here)
AUTOPILOTS = ("ours", "ardupilot", "px4")


class FieldFileError(ValueError):
    pass


@dataclass(frozen=True)
class FieldSpec:
    origin: HomePosition  # cell (0, 0)'s centre
    grid: GridConfig
    cell_m: float = DEFAULT_CELL_M
    connect: str | None = None  # the companion's pymavlink address for this vehicle
    instance: int | None = None
    physics: str | None = None
    #: the paddock's edge is visible (the SITL renders a track round the grass): the companion
    #: reads a border not in view as evidence (`SearchSpec.field_edge`)
    edge: bool = False
    #: the autopilot family the vehicle speaks as (`sitl --dialect`): the companion picks its
    #: dialect by it; files written before dialects existed read as px4
    dialect: str = "px4"
    #: the camera's video stream (`sitl --video-port`): what `run --camera video` opens and
    #: the SDP file describing it (written next to the field file; relative to it)
    video_uri: str | None = None
    video_sdp: str | None = None
    #: who flies the vehicle: "ours" (our SITL, sim.mavlink), "ardupilot" or "px4" (the real
    #: binary on our world's physics, sim.bridges); None: a file from before this entry (ours)
    autopilot: str | None = None
    #: the companion's `run --camera` spec for this vehicle's camera (a camera component on an
    #: address of its own, beside a real autopilot); None: the one on the vehicle's link
    camera: str | None = None
    #: the vehicle's launch pad in the field frame (north, east m), where a real autopilot's
    #: world sets it down: its HOME_POSITION is its GPS's fix there, not the pad
    launch_ne: tuple[float, float] | None = None
    #: the real field the SITL renders (`sitl --field`): the path of its field.json (`uavsearch
    #: field`), whose grid, heading, mask and fence `run --field` flies; None: the rectangle
    polygon: str | None = None
    #: how many vehicles share this one field (`sitl --count N --one-field`: the same targets,
    #: each vehicle its own start cell; `run --fleet` flies them together); None: a field of its own
    team: int | None = None

    def __post_init__(self) -> None:
        if self.dialect not in DIALECTS:
            raise FieldFileError(f"dialect must be one of {', '.join(DIALECTS)} (got {self.dialect!r})")

    def to_dict(self) -> dict[str, Any]:
        return {"kind": KIND,
                "origin": {"lat": self.origin.lat_deg, "lon": self.origin.lon_deg, "alt": self.origin.alt_m},
                "cell_m": self.cell_m, "width": self.grid.width, "height": self.grid.height,
                "targets": self.grid.n_targets, "distribution": self.grid.distribution,
                "motion": self.grid.motion, "target_period": self.grid.target_period,
                "connect": self.connect, "instance": self.instance, "physics": self.physics, "edge": self.edge,
                "dialect": self.dialect,
                "video": None if self.video_uri is None else {"uri": self.video_uri, "sdp": self.video_sdp},
                "autopilot": self.autopilot, "camera": self.camera,
                "launch_ne": None if self.launch_ne is None else list(self.launch_ne),
                **({} if self.team is None else {"team": self.team}),
                # altitude levels the companion flies (docs/altitude.md), with their detection
                # table: only where there are levels, so files without them read as before
                **({} if self.grid.levels == 1 else {"levels": self.grid.levels,
                                                     "detection": self.grid.detection.to_dict()}),
                **({} if self.polygon is None else {"polygon": self.polygon})}


def write_field(path: Path, spec: FieldSpec, seed: int | None = None, **extra: Any) -> None:
    atomic_write_json(path, {**spec.to_dict(), "provenance": stamp(None, seed, **extra)})


def read_field(path: Path) -> FieldSpec:
    """The field a `sitl` wrote; every problem names the file and the value."""
    try:
        d = json.loads(Path(path).read_text())
    except FileNotFoundError as e:
        raise FieldFileError(f"field file {path} does not exist (uavsearch sitl writes it: --field-out)") from e
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise FieldFileError(f"field file {path} is not readable JSON ({' '.join(str(e).split())[:160]})") from e
    if not isinstance(d, dict) or d.get("kind") != KIND:
        raise FieldFileError(f"{path} is not a uavsearch field file (kind {d.get('kind') if isinstance(d, dict) else None!r})")
    try:
        o = d["origin"]
        origin = HomePosition(float(o["lat"]), float(o["lon"]), float(o["alt"]))
        grid = GridConfig(width=int(d["width"]), height=int(d["height"]), n_targets=int(d["targets"]),
                          distribution=d["distribution"], motion=d["motion"],
                          target_period=int(d.get("target_period", 3)), levels=int(d.get("levels", 1)),
                          detection=d.get("detection"))
        cell_m = float(d["cell_m"])
    except (KeyError, TypeError, ValueError, ConfigError) as e:
        raise FieldFileError(f"field file {path}: bad or missing entry ({type(e).__name__}: {e})") from e
    if not cell_m > 0:
        raise FieldFileError(f"field file {path}: cell_m must be positive (got {cell_m})")
    edge = d.get("edge", False)  # field files written before the edge was rendered: none
    if not isinstance(edge, bool):
        raise FieldFileError(f"field file {path}: edge must be true or false (got {edge!r})")
    autopilot = d.get("autopilot")
    camera = d.get("camera")
    launch = d.get("launch_ne")
    if launch is not None:
        try:
            launch = (float(launch[0]), float(launch[1]))
        except (TypeError, ValueError, IndexError, KeyError):
            raise FieldFileError(f"field file {path}: launch_ne must be [north, east] in metres (got {launch!r})") from None
    if camera is not None and not isinstance(camera, str):
        raise FieldFileError(f"field file {path}: camera must be a --camera spec such as mavlink:udpin:0.0.0.0:14560 "
                             f"(got {camera!r})")
    if autopilot not in (None, *AUTOPILOTS):
        raise FieldFileError(f"field file {path}: autopilot must be one of {', '.join(AUTOPILOTS)} (got {autopilot!r})")
    team = d.get("team")  # one field shared by several vehicles (sitl --one-field); older files: none
    if team is not None and (isinstance(team, bool) or not isinstance(team, int) or team < 2):
        raise FieldFileError(f"field file {path}: team must be the number of vehicles on the field, >= 2 (got {team!r})")
    dialect = d.get("dialect", "px4")  # field files written before dialects: PX4's
    if dialect not in DIALECTS:
        raise FieldFileError(f"field file {path}: dialect must be one of {', '.join(DIALECTS)} (got {dialect!r})")
    video = d.get("video")  # field files written before the video stream: none
    uri = sdp = None
    if video is not None:
        if not isinstance(video, dict) or not isinstance(video.get("uri"), str) or \
                not isinstance(video.get("sdp"), str | None):
            raise FieldFileError(f"field file {path}: video must be {{\"uri\": ..., \"sdp\": ...}} (got {video!r})")
        uri, sdp = video["uri"], video.get("sdp")
        if sdp is not None and not Path(sdp).is_absolute():
            sdp = str(Path(path).parent / sdp)
    polygon = d.get("polygon")
    if polygon is not None:
        if not isinstance(polygon, str):
            raise FieldFileError(f"field file {path}: polygon must be the path of a field.json (got {polygon!r})")
        if not Path(polygon).is_absolute():
            polygon = str(Path(path).parent / polygon)
    return FieldSpec(origin, grid, cell_m, d.get("connect"), d.get("instance"), d.get("physics"), edge, dialect=dialect,
                     video_uri=uri, video_sdp=sdp, autopilot=autopilot, camera=camera,
                     launch_ne=launch, polygon=polygon, team=team)
