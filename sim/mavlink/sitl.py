"""A software-in-the-loop vehicle: flight model + sensors + field + MAVLink endpoint, stepped
in lock-step at a fixed rate, real time or faster (speedup), on PX4 SITL's ports.

Ports and ids as PX4 SITL (ROMFS/px4fmu_common/init.d-posix/px4-rc.mavlink, rcS): instance N
is MAVLink system N+1; its offboard/API link sends from UDP 14580+N to 14540+N (MAVSDK,
companion computers: `udpin://0.0.0.0:14540`), its GCS link from 18570+N to 14550 for every
instance (QGroundControl and MAVProxy listen there and tell vehicles apart by system id).
Every port can be overridden, which tests do to stay clear of each other.

The vehicle speaks as PX4 (dialect "px4", the default) or as ArduCopter ("ardupilot",
dialects/ardupilot.py) on the same ports either way, so a companion reaches instance N at UDP
14540+N whichever autopilot it stands in for (a real ArduPilot SITL would be reached on TCP
5760+10N or through MAVProxy's --out instead; docs/sitl.md).
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
import traceback
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from provenance import stamp
from sim.gridworld import BatchGridWorld, GridConfig
from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsConfig, GpsModel
from sim.vehicle.model import FlightModel
from sim.vehicle.scene import FieldScene, check_camera_px

from .camera_component import MAV_COMP_ID_CAMERA, CameraComponent, CameraInfo
from .component_link import SharedLink
from .dialects import DIALECTS, make_dialect
from .geofence import Geofence
from .runner import BackgroundRunner, pace
from .tlog import TlogWriter
from .udp import UdpLink
from .vehicle import MavlinkVehicle
from .video import VideoConfig, VideoStreamer

TICK_S = 0.02
LOCKSTEP_TIMEOUT_S = 5.0  # wall-clock seconds a companion may think before time runs on
log = logging.getLogger(__name__)


@dataclass
class SitlConfig:
    instance: int = 0
    speedup: float = 1.0  # 0: as fast as the machine allows
    physics: str = "pybullet"  # pybullet | kinematic
    home: HomePosition = field(default_factory=HomePosition)
    grid: GridConfig = field(default_factory=GridConfig)
    episode_seed: int = 0
    seed: int = 0
    camera: bool | None = None  # None: on for pybullet; on a kinematic body it renders a PyBullet scene of its own
    camera_px: int = 50
    #: the camera component's video stream (an RTP/H.264 URI served by another process, e.g.
    #: "udp://127.0.0.1:5600"): carried in VIDEO_STREAM_INFORMATION; None, no video stream
    camera_video_uri: str | None = None
    #: the paddock's edge: a headland track round the field's grass (`sim.vehicle.field`), which
    #: the companion registers its position on near the borders; False: grass to the horizon
    field_edge: bool = True
    #: simulated seconds per grid-world step of the targets' motion: the companion's decision
    #: period (autopilot_bridge SearchSpec.decision_period_s), so cattle move at the grid world's
    #: pace per decision (a target moves on every target_period-th step), from the first arming
    target_step_s: float = 4.0
    signing_key: bytes | None = None
    tlog: Path | None = None
    gcs_link: bool = True
    host: str = "127.0.0.1"
    bind: str = "0.0.0.0"  # the local address the vehicle's ports are bound to (`sitl --bind`)
    geofence: Geofence = field(default_factory=Geofence)
    gps: GpsConfig = field(default_factory=GpsConfig)  # the receiver's error model
    #: hold simulated time after sending a frame asked for ahead (a companion's decision point)
    #: until the companion's next command, at most LOCKSTEP_TIMEOUT_S of wall-clock time: PX4
    #: SITL's lockstep, extended to the companion, so a loaded machine cannot change a flight
    companion_lockstep: bool = False
    system_id: int | None = None  # None: instance + 1, as PX4 SITL
    #: the autopilot family the vehicle speaks as: px4 | ardupilot (dialects/)
    dialect: str = "px4"
    #: ardupilot: simulated seconds from boot until the EKF has an absolute horizontal position
    #: (arming in GUIDED waits for it; the real ArduCopter SITL takes ~40 s, tests want few)
    ekf_delay_s: float = 3.0
    #: the camera's RTP/H.264 stream (`sitl --video-port`, sim/mavlink/video.py); port 0: off
    video: VideoConfig = field(default_factory=VideoConfig)
    #: a real field (`sim.field.PolygonField`, from `uavsearch field`): its grid (at its heading),
    #: its polygon rendered, the spawn and targets on its searchable cells; `home` and `grid`
    #: must be its origin and size. None: today's north-aligned rectangle
    polygon: Any = None
    # port overrides (None: PX4 SITL's numbering for this instance)
    api_local_port: int | None = None
    api_remote_port: int | None = None
    gcs_local_port: int | None = None
    gcs_remote_port: int | None = None
    #: the cell (x, y) the vehicle stands on at start; None: the episode's start cell (one
    #: vehicle's field). A fleet on one field (`sitl --count N --one-field`) gives each vehicle
    #: the same episode and its own start cell (sim.gridworld.team.team_starts)
    spawn_cell: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if not 0 <= self.instance < 40:
            raise ValueError("instance must be in 0..39 (ports 14540+N must not meet 14580+M)")
        if self.system_id is not None and not 1 <= self.system_id <= 255:
            raise ValueError(f"system_id must be in 1..255 (got {self.system_id})")
        for name in ("api_local_port", "api_remote_port", "gcs_local_port", "gcs_remote_port"):
            port = getattr(self, name)
            if port is not None and not 1 <= port <= 65535:
                raise ValueError(f"{name} must be a UDP port in 1..65535 (got {port})")
        if self.geofence.max_horizontal_m <= 0 or self.geofence.max_altitude_m <= 0:
            raise ValueError(f"geofence limits must be positive (got {self.geofence})")
        if not self.target_step_s > 0:
            raise ValueError(f"target_step_s must be > 0 (got {self.target_step_s})")
        try:
            socket.inet_aton(self.bind)
        except OSError:
            raise ValueError(f"bind must be an IPv4 address such as 0.0.0.0 or 127.0.0.1 (got {self.bind!r})") from None
        if self.dialect not in DIALECTS:
            raise ValueError(f"dialect must be one of {', '.join(DIALECTS)} (got {self.dialect!r})")
        if not (0.0 <= self.ekf_delay_s < 3600.0):
            raise ValueError(f"ekf_delay_s must be in [0, 3600) s (got {self.ekf_delay_s})")
        if self.speedup < 0:
            raise ValueError("speedup must be >= 0 (0: as fast as possible)")
        if self.physics not in ("pybullet", "kinematic"):
            raise ValueError(f"physics must be 'pybullet' or 'kinematic' (got {self.physics!r})")
        if self.camera is None:
            self.camera = self.physics == "pybullet"
        check_camera_px(self.camera_px)
        if self.camera_video_uri is not None:
            from .camera_component import CameraInfo

            CameraInfo(video_uri=self.camera_video_uri)  # the same check as the camera's, now

    def to_dict(self) -> dict[str, Any]:
        """The config for provenance records; the signing key itself is never written out."""
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("signing_key", "grid", "polygon")}
        if self.polygon is not None:
            d["polygon"] = {"source": self.polygon.source, "heading_deg": self.polygon.heading_deg,
                            "width": self.polygon.width, "height": self.polygon.height}
        d.update(home=asdict(self.home), geofence=asdict(self.geofence), grid=self.grid.to_dict(), gps=asdict(self.gps),
                 signing=self.signing_key is not None, tlog=None if self.tlog is None else str(self.tlog),
                 sysid=self.sysid, api_ports=self.api_ports, gcs_ports=self.gcs_ports, video=asdict(self.video))
        return d

    @property
    def sysid(self) -> int:
        return self.instance + 1 if self.system_id is None else self.system_id

    @property
    def api_ports(self) -> tuple[int, int]:
        """(vehicle's local port, remote port it sends to) of the offboard/API link."""
        return (_or(self.api_local_port, 14580 + self.instance), _or(self.api_remote_port, 14540 + self.instance))

    @property
    def gcs_ports(self) -> tuple[int, int]:
        """(vehicle's local port, remote port it sends to) of the GCS link."""
        return _or(self.gcs_local_port, 18570 + self.instance), _or(self.gcs_remote_port, 14550)


def _or(value: int | None, default: int) -> int:
    return default if value is None else value


class Sitl(BackgroundRunner):
    """Build with a config, then `start()` (background thread) or `run()` (foreground)."""

    def __init__(self, cfg: SitlConfig, model: FlightModel | None = None) -> None:
        """model: a flight model stepped by someone else (a fleet member, sim/mavlink/fleet.py);
        None builds and steps this vehicle's own, as cfg.physics says."""
        self.cfg = cfg
        # the field: episode, home at the spawn point (the field's cell (0, 0) lies at -spawn in
        # local NED), rendered paddock and camera; shared with the worlds real autopilots fly
        self.scene = FieldScene(cfg.grid, cfg.home, cfg.episode_seed, cfg.target_step_s, polygon=cfg.polygon,
                                spawn_cell=cfg.spawn_cell)
        self.episode = self.scene.episode
        self.home = self.scene.home
        self.field_origin = self.scene.field_origin
        self.spawn_ne = self.scene.spawn_ne
        self._field = None
        self._scene: int | None = None  # a render-only PyBullet world, for a fleet member's camera
        self._own_model = model is None
        if model is not None:
            self.model = model
        elif cfg.physics == "pybullet":
            from sim.vehicle.quadrotor import PyBulletQuadrotor

            self.model = PyBulletQuadrotor()
        else:
            from sim.vehicle.kinematic import KinematicVehicle

            self.model = KinematicVehicle()
        has_camera = False
        if cfg.camera:
            if self._own_model and hasattr(self.model, "cid"):
                cid = self.model.cid
            else:  # a fleet's world holds every vehicle, a kinematic body has none: a scene to render
                import pybullet

                cid = self._scene = pybullet.connect(pybullet.DIRECT)
            # the PyBullet world is centred on the spawn point: the field is shifted to match
            self.scene.attach(cid, cfg.seed, cfg.field_edge, cfg.camera_px)
            self._field, self._cam = self.scene.field, self.scene.cam
            has_camera = True
        self.video: VideoStreamer | None = None
        self._video_held = False  # the vehicle held for the companion at the last video check
        if cfg.video.enabled and has_camera:
            self.video = VideoStreamer(cfg.video, cfg.camera_px, cfg.camera_px)
        self.tlog = TlogWriter(cfg.tlog, meta=stamp(cfg.to_dict(), cfg.seed, kind="sitl tlog")) if cfg.tlog else None
        sink = self.tlog.write if self.tlog else None
        links = [UdpLink(*cfg.api_ports, host=cfg.host, system_id=cfg.sysid, signing_key=cfg.signing_key,
                         on_bytes=sink, bind=cfg.bind)]
        if cfg.gcs_link:
            try:
                links.append(UdpLink(*cfg.gcs_ports, host=cfg.host, system_id=cfg.sysid,
                                     signing_key=cfg.signing_key, on_bytes=sink, log_outgoing=False, bind=cfg.bind))
            except OSError:
                links[0].close()
                if self.video is not None:
                    self.video.close()
                raise
        self.gps = GpsModel(self.home, cfg.seed, cfg.gps)
        options = {"ekf_delay_s": cfg.ekf_delay_s, "sysid": cfg.sysid} if cfg.dialect == "ardupilot" else {}
        self.vehicle = MavlinkVehicle(self.model, links, self.home, self.gps, system_id=cfg.sysid,
                                      signing=cfg.signing_key is not None,
                                      dialect=make_dialect(cfg.dialect, **options))
        #: the downward camera: a MAVLink camera component (100) on the vehicle's links
        self.camera: CameraComponent | None = self._camera_component(links) if has_camera else None
        for name, value in (("GF_MAX_HOR_DIST", cfg.geofence.max_horizontal_m),
                            ("GF_MAX_VER_DIST", cfg.geofence.max_altitude_m)):
            ok, why = self.vehicle.params.set(name, value)
            if not ok:
                for link in links:
                    link.close()
                if self.video is not None:
                    self.video.close()
                raise ValueError(f"geofence: {why}")
        self.vehicle.lockstep = cfg.companion_lockstep
        self.lockstep_timeouts = 0
        self.t = 0.0
        self.errors: list[str] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._update_targets()

    # -- the field's truth (never sent over MAVLink) --------------------------------------
    @property
    def _motion_t0(self) -> float | None:
        """Simulated time of the first arming (the targets move from then on)."""
        return self.scene.motion_t0

    def target_cells(self, t: float | None = None) -> np.ndarray:
        """Targets' cells now (FieldScene.target_cells)."""
        return self.scene.target_cells(self.t if t is None else t)

    def vehicle_cell(self) -> np.ndarray:
        """The true cell under the vehicle (fractional)."""
        return self.scene.vehicle_cell(self.model.state.position_ned)

    def _update_targets(self) -> None:
        self.scene.update_targets(self.t)

    def _render(self, position_ned: np.ndarray, yaw: float) -> np.ndarray:
        return self.scene.render(self.t, position_ned, yaw)

    def render_now(self) -> np.ndarray:
        """What the camera sees now: the field with the targets where they are at self.t."""
        s = self.model.state
        return self._render(s.position_ned.copy(), float(s.attitude_rpy[2]))

    def _camera_component(self, links: list[UdpLink]) -> CameraComponent:
        """The camera as component 100 of the vehicle's system, on the vehicle's own links (as
        behind a MAVLink router), ticked after the vehicle; its captures asked for ahead hold
        the clock under companion lockstep, a command to it releases it."""
        cfg, v = self.cfg, self.vehicle
        info = CameraInfo(width=cfg.camera_px, height=cfg.camera_px, hfov_deg=self._cam.fov,
                          video_uri=cfg.camera_video_uri)
        cam = CameraComponent(self.render_now, lambda: self.t, [SharedLink(link, MAV_COMP_ID_CAMERA) for link in links],
                              system_id=cfg.sysid, info=info, position=lambda: self.model.state.position_ned.copy(),
                              rate_hz=lambda: v.params["UAVS_CAM_RATE"], on_command=v.release,
                              on_decision_point=v.hold)
        v.components.append(cam)
        return cam

    # -- running -------------------------------------------------------------------------
    def step(self) -> None:
        self.model.step(TICK_S)
        self.t += TICK_S
        self._note_arming()
        self.vehicle.tick(self.t)
        self._stream_video()

    def _stream_video(self, t: float | None = None) -> None:
        """Render the video stream's frame when one is due at simulated time t (default: this
        vehicle's; a fleet passes its own, its quiet vehicles not being ticked); the encoder's
        thread does the rest."""
        if self.video is None:
            return
        t = self.t if t is None else t
        # a companion-lockstep hold (at a capture asked for ahead) starts on this tick: its frame
        # goes out whether or not the tick is on the stream's lattice, or the companion, waiting
        # for the frame of its instant, would wait out the hold
        held = self.vehicle.hold_for_companion
        hold_starts, self._video_held = held and not self._video_held, held
        if hold_starts or self.video.due(t):
            s = self.model.state
            self.video.submit(self._render(s.position_ned.copy(), float(s.attitude_rpy[2])), t)

    def _note_arming(self) -> None:
        self.scene.note_armed(self.t, self.model.state.armed)

    def tick(self, t: float, serve: bool = True, sampled: bool = False) -> None:
        """The MAVLink side's tick after someone else stepped the model to t (fleets); a
        failing tick is recorded and the vehicle stays on the link. serve=False: the caller
        has just answered what arrived (a fleet polls every vehicle's sockets at once);
        sampled: the caller has taken this tick's GPS fix (MavlinkVehicle.sample_gps)."""
        self.t = t
        self._note_arming()
        try:
            self.vehicle.tick(t, serve, sampled)
        except Exception:
            self.errors.append(traceback.format_exc())
            log.exception("SITL %d tick failed at t=%.2f", self.cfg.instance, t)

    def run(self, duration: float | None = None) -> None:
        wall0 = time.monotonic()
        v = self.vehicle
        while not self._stop.is_set() and (duration is None or self.t < duration):
            if v.hold_for_companion:
                held = time.monotonic() - v.hold_wall_t
                if held > LOCKSTEP_TIMEOUT_S:
                    v.hold_for_companion = False
                    self.lockstep_timeouts += 1
                else:
                    ready, _, _ = select.select([link.sock for link in v.links], [], [], 0.01)
                    if ready:
                        v.service()
                    if not v.hold_for_companion:  # released: pace on from here, not catch up
                        wall0 += time.monotonic() - v.hold_wall_t
                    continue
            try:
                self.step()
            except Exception:  # a bug in one tick must not take the vehicle off the link
                self.errors.append(traceback.format_exc())
                log.exception("SITL tick failed at t=%.2f", self.t)
                if len(self.errors) > 100:
                    raise
            if self.cfg.speedup > 0:
                pace(wall0, self.t, self.cfg.speedup, [link.sock for link in v.links],
                     lambda _ready: v.service())

    def _thread_name(self) -> str:
        return f"sitl-{self.cfg.instance}"

    def _close(self) -> None:
        for link in self.vehicle.links:
            link.close()
        if self.video is not None:
            self.video.close()
        if self.tlog:
            self.tlog.close()
        if self._own_model:
            self.model.close()
        if self._scene is not None:
            import pybullet

            if pybullet.isConnected(self._scene):
                pybullet.disconnect(self._scene)
            self._scene = None

    def grid_world(self) -> BatchGridWorld:
        return BatchGridWorld(self.episode, self.cfg.seed)
