"""Our world as a real autopilot's physics: the motor-driven PyBullet body, the field and its
targets (sim.vehicle.scene, as our SITL builds them), the truth record, the camera hook, and
the autopilot binary flying it all through its simulator interface.

    with AutopilotWorld(AutopilotWorldConfig(autopilot="px4", instance=20)) as world:
        address = world.companion_address()   # pymavlink address of the autopilot's API link
        ...                                   # the companion flies; world.truth fills
        frame = world.render(position_ned, yaw)   # a camera component's render function
        stamp = world.autopilot_clock_s()         # and its clock (the autopilot's boot clock)

Clocks (measured, docs/autopilots.md): the world's simulated time `t` starts at 0 before the
first physics step. PX4's clock (hrt; time_boot_ms; GPS_RAW_INT.time_usec, the HIL_GPS stamp)
is the HIL_SENSOR time_usec we send: t + 1 s. ArduPilot's boot clock is the sum of our JSON
timestamps' steps from 0 (SIM_JSON.cpp: time_now_us += deltat): t itself; its GPS_RAW_INT.time_usec
is the boot time of the last fix.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.gridworld import GridConfig
from sim.mavlink.camera_component import CameraComponent, CameraInfo
from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsConfig
from sim.vehicle.motor_quad import MotorQuadrotor, hover_throttle
from sim.vehicle.scene import FieldScene, check_camera_px

from .ardupilot_json import ArduPilotJsonBridge, json_port
from .processes import (
    ARDUPILOT_ENV,
    PX4_ENV,
    ArduPilotLaunch,
    AutopilotProcess,
    Px4Launch,
    find_binary,
    px4_ports,
    start_ardupilot,
    start_px4,
    wait_alive,
)
from .px4_hil import EarthField, Px4HilBridge, px4_params, simulator_port

AUTOPILOTS = ("ardupilot", "px4")
TRUTH_PERIOD_S = 0.02  # the truth record's step: our SITL's tick


@dataclass(frozen=True)
class AutopilotWorldConfig:
    autopilot: str  # ardupilot | px4
    instance: int = 0
    #: ArduPilot: its --speedup (it paces itself, we answer at once); PX4: our pacing of the
    #: lockstep (and PX4_SIM_SPEED_FACTOR); 0 for PX4: as fast as the machine allows
    speedup: float = 1.0
    binary: str | Path | None = None  # None: $ARDUPILOT_SITL / $PX4_SITL
    home: HomePosition = field(default_factory=HomePosition)  # the field's cell (0, 0)
    grid: GridConfig = field(default_factory=GridConfig)
    episode_seed: int = 0
    seed: int = 0
    camera: bool = True
    camera_px: int = 50
    field_edge: bool = True
    target_step_s: float = 4.0
    gps: GpsConfig = field(default_factory=GpsConfig)  # PX4's receiver (ArduPilot simulates its own)
    #: ArduPilot: SERIAL0 (the API link) goes over UDP to 127.0.0.1:api_port (default 14540+N);
    #: PX4 keeps its own port plan (processes.px4_ports)
    api_port: int | None = None
    #: ArduPilot: SERIAL1 to a ground station on 127.0.0.1:gcs_port; None: left on TCP 5762+10*N
    gcs_port: int | None = 14550
    params: dict[str, float] = field(default_factory=dict)  # extra autopilot parameters
    #: the downward camera as a MAVLink camera component (100) on a UDP endpoint of its own,
    #: as on a real drone beside its flight controller: it listens on camera_port + 40 and
    #: sends to camera_port, where the companion opens `--camera mavlink:udpin:0.0.0.0:PORT`
    #: (None: 14560 + instance); 0: no camera component
    camera_port: int | None = None
    keep_dir: bool = False  # keep the autopilot's working directory (logs) after stop
    #: where the vehicle stands at the start (x, y); None: the episode's start cell. A fleet on
    #: one field (`sitl --count N --one-field`) gives each world the team grid world's start
    spawn_cell: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if self.autopilot not in AUTOPILOTS:
            raise ValueError(f"autopilot must be one of {AUTOPILOTS} (got {self.autopilot!r})")
        if not 0 <= self.instance <= 39:
            raise ValueError(f"instance must be in 0..39 (got {self.instance})")
        if self.speedup < 0 or (self.autopilot == "ardupilot" and self.speedup == 0):
            raise ValueError(f"speedup must be > 0 (>= 0 for PX4: 0 runs as fast as possible; got {self.speedup})")
        if not self.target_step_s > 0:
            raise ValueError(f"target_step_s must be > 0 (got {self.target_step_s})")
        check_camera_px(self.camera_px)

    @property
    def sysid(self) -> int:
        return self.instance + 1  # both autopilots' SITL numbering (MAV_SYS_ID, SYSID_THISMAV)

    def to_dict(self) -> dict[str, Any]:
        return {"autopilot": self.autopilot, "instance": self.instance, "speedup": self.speedup,
                "binary": None if self.binary is None else str(self.binary),
                "home": {"lat": self.home.lat_deg, "lon": self.home.lon_deg, "alt": self.home.alt_m},
                "grid": self.grid.to_dict(), "episode_seed": self.episode_seed, "seed": self.seed,
                "camera": self.camera, "camera_px": self.camera_px, "field_edge": self.field_edge, "target_step_s": self.target_step_s,
                "api_port": self.api_port, "gcs_port": self.gcs_port, "params": dict(self.params),
                "camera_port": self.camera_ports[1] if self.camera_ports else None,
                **({} if self.spawn_cell is None else {"spawn_cell": [int(v) for v in self.spawn_cell]})}

    @property
    def camera_ports(self) -> tuple[int, int] | None:
        """(the camera component's local port, the companion's port it sends to); None: none."""
        if not self.camera or self.camera_port == 0:
            return None
        remote = 14560 + self.instance if self.camera_port is None else self.camera_port
        return remote + 40, remote


class AutopilotWorld:
    """start() (the bridge listens, then the binary starts), stop() (SIGKILL, close). Every
    method is safe to call from another thread than the bridge's."""

    def __init__(self, cfg: AutopilotWorldConfig) -> None:
        self.cfg = cfg
        self.scene = FieldScene(cfg.grid, cfg.home, cfg.episode_seed, cfg.target_step_s, spawn_cell=cfg.spawn_cell)
        self.home = self.scene.home  # the spawn point: the autopilot's home
        self.body = MotorQuadrotor()
        self.lock = threading.Lock()
        if cfg.camera:
            self.scene.attach(self.body.cid, cfg.seed, cfg.field_edge, cfg.camera_px)
        #: (the autopilot's clock, north, east in the field's frame): stamped as the companion
        #: stamps its decisions (PX4's clock runs 1 s ahead of t; scored on t, every PX4 decision
        #: was compared with where the vehicle was a second later, mid-leg: NEES 231)
        self.truth: list[tuple[float, float, float]] = []
        self.height: list[float] = []  # true height over the field at the same times
        self._next_truth = 0.0
        self.process: AutopilotProcess | None = None
        self.camera: CameraComponent | None = None
        if cfg.autopilot == "ardupilot":
            self.bridge: ArduPilotJsonBridge | Px4HilBridge = ArduPilotJsonBridge(
                self.body, json_port(cfg.instance), on_step=self._on_step, lock=self.lock)
            self._clock_offset_s = 0.0  # measured: time_boot_ms / 1e3 - t in [-70, -2] ms at arrival
        else:
            self.bridge = Px4HilBridge(self.body, simulator_port(cfg.instance), self.home, seed=cfg.seed, gps=cfg.gps,
                                       speedup=cfg.speedup, on_step=self._on_step, lock=self.lock)
            self._clock_offset_s = self.bridge.time_offset_usec / 1e6  # measured: exact

    # -- what the companion and the camera need --------------------------------------------
    @property
    def t(self) -> float:
        """The world's simulated seconds (0 at the first physics step)."""
        return self.bridge.t

    def autopilot_clock_s(self) -> float:
        """Now on the autopilot's boot clock (time_boot_ms / 1e3): what a camera component
        stamps its frames with, so the companion sees one clock."""
        return self.bridge.t + self._clock_offset_s

    def render(self, position_ned: np.ndarray, yaw: float) -> np.ndarray:
        """The downward camera's frame now (a camera component's render function)."""
        with self.lock:
            return self.scene.render(self.bridge.t, position_ned, yaw)

    def render_now(self) -> np.ndarray:
        """The frame from where the body is now, on one step's state (the world's lock)."""
        with self.lock:
            s = self.body.state
            return self.scene.render(self.bridge.t, s.position_ned.copy(), float(s.attitude_rpy[2]))

    def camera_address(self) -> str | None:
        """The companion's `--camera` spec for this world's camera component (None: none)."""
        ports = self.cfg.camera_ports
        return None if ports is None else f"mavlink:udpin:0.0.0.0:{ports[1]}"

    def _start_camera(self) -> None:
        """The camera component on its own UDP endpoint, stamping frames on the autopilot's
        boot clock, so the companion reads frames and telemetry on one clock."""
        local, remote = self.cfg.camera_ports
        info = CameraInfo(width=self.cfg.camera_px, height=self.cfg.camera_px, hfov_deg=self.scene.cam.fov)
        self.camera = CameraComponent.on_udp(self.render_now, self.autopilot_clock_s, local, remote,
                                             system_id=self.cfg.sysid, info=info,
                                             position=lambda: self.body.state.position_ned.copy())
        self.camera.start()

    def companion_address(self) -> str:
        """The pymavlink address of the autopilot's API link, as the companion opens it."""
        if self.cfg.autopilot == "ardupilot":
            return f"udpin:127.0.0.1:{self.api_port}"
        ports = px4_ports(self.cfg.instance)
        if self.cfg.instance <= 9:
            return f"udpin:0.0.0.0:{ports['onboard_remote']}"
        # instances > 9 all send to 14549 (px4-rc.mavlink): talk first to the instance's own port
        return f"udpout:127.0.0.1:{ports['onboard_local']}"

    @property
    def api_port(self) -> int:
        return self.cfg.api_port if self.cfg.api_port is not None else 14540 + self.cfg.instance

    def target_cells(self, t: float | None = None) -> np.ndarray:
        return self.scene.target_cells(self.bridge.t if t is None else t)

    def vehicle_cell(self) -> np.ndarray:
        return self.scene.vehicle_cell(self.body.state.position_ned)

    def stats(self) -> dict[str, Any]:
        b = self.bridge
        d: dict[str, Any] = {"t": b.t, "armed": b.armed}
        if isinstance(b, ArduPilotJsonBridge):
            d.update(frames=b.frames, duplicates=b.duplicates, restarts=b.restarts)
        else:
            d.update(steps=b.steps, controls=b.controls_received, lockstep_timeouts=b.lockstep_timeouts)
        return d

    # -- life cycle ----------------------------------------------------------------------
    def _on_step(self, t: float) -> None:
        self.scene.note_armed(t, self.bridge.armed)
        if self.bridge.armed and not self.body.state.armed:  # the state says what the autopilot did
            self.body.arm()
        elif not self.bridge.armed and self.body.state.armed:
            self.body.disarm()
        if t + 1e-9 >= self._next_truth:
            p = self.body.state.position_ned
            self.truth.append((t + self._clock_offset_s, *self.scene.field_ne(p)))
            self.height.append(float(-p[2]))
            self._next_truth += TRUTH_PERIOD_S

    def start(self, alive_check_s: float = 1.0) -> AutopilotWorld:
        cfg = self.cfg
        self.bridge.start()
        try:
            if cfg.autopilot == "ardupilot":
                binary = find_binary(cfg.binary, ARDUPILOT_ENV, "ArduPilot SITL (arducopter)")
                hover = round(hover_throttle(self.body.af, self.body.motors), 3)
                self.process = start_ardupilot(ArduPilotLaunch(
                    binary, cfg.instance, self.home, self.api_port, cfg.gcs_port, speedup=cfg.speedup,
                    params={"MOT_THST_HOVER": hover, "MOT_THST_EXPO": self.body.motors.thrust_expo, **cfg.params},
                    keep_dir=cfg.keep_dir))
            else:
                binary = find_binary(cfg.binary, PX4_ENV, "PX4 SITL (px4)")
                self.process = start_px4(Px4Launch(binary, cfg.instance, self.home,
                                                   speedup=cfg.speedup if cfg.speedup > 0 else 1.0,
                                                   params={**px4_params(EarthField()), **cfg.params},
                                                   keep_dir=cfg.keep_dir))
            wait_alive(self.process, alive_check_s)
            if cfg.camera_ports is not None:
                self._start_camera()
        except BaseException:
            self.stop()
            raise
        return self

    def wait_physics(self, timeout: float = 30.0) -> None:
        """Until the autopilot has taken its first physics steps."""
        end = time.monotonic() + timeout
        while self.bridge.t <= 0:
            if self.process is not None and not self.process.alive:
                raise RuntimeError(f"the autopilot exited:\n{self.process.tail()}")
            if time.monotonic() > end:
                raise TimeoutError(f"no physics step within {timeout:g} s")
            time.sleep(0.02)

    def stop(self) -> None:
        self.bridge._stop.set()  # first: the autopilot's end closing the link is no error then
        if self.camera is not None:
            self.camera.close()
        if self.process is not None:
            self.process.stop()
        self.bridge.stop()
        self.body.close()

    def __enter__(self) -> AutopilotWorld:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
