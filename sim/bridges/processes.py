"""Start and stop the real autopilot binaries, each in a temporary working directory of its own.

Facts measured on these binaries (/work/shared/peers/build_*.sh headers):
  - ArduCopter exits silently at its first physics step when the process that started it has
    gone: it is kept as a Popen held open by the process that runs the world.
  - While it waits for physics it ignores SIGTERM: it is stopped with SIGKILL.
  - PX4 stops on SIGTERM or SIGKILL alike; SIGKILL is used for both (nothing is to be saved).
Each binary's stdout and stderr go to a log file in its working directory (`log_path`), read
back on failure (`tail`).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from sim.vehicle.geo import HomePosition

ARDUPILOT_ENV = "ARDUPILOT_SITL"
PX4_ENV = "PX4_SITL"


class AutopilotStartError(RuntimeError):
    pass


def find_binary(explicit: str | Path | None, env: str, what: str) -> Path:
    """The binary from an explicit path, else from the environment variable; a clear error
    naming both when neither gives an executable file."""
    raw = explicit if explicit is not None else os.environ.get(env)
    if not raw:
        raise AutopilotStartError(f"no {what} binary: pass --autopilot-bin or set {env}")
    path = Path(raw).expanduser()
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise AutopilotStartError(f"{what} binary {path} is not an executable file (from "
                                  f"{'--autopilot-bin' if explicit is not None else env})")
    return path.resolve()


class AutopilotProcess:
    """A started binary: `alive`, `tail()`, `stop()` (SIGKILL, then the working dir is removed
    unless keep_dir)."""

    def __init__(self, argv: list[str], cwd: Path, env: Mapping[str, str], keep_dir: bool = False) -> None:
        self.argv, self.cwd, self.keep_dir = argv, cwd, keep_dir
        self.log_path = cwd / "autopilot.log"
        self._log = open(self.log_path, "wb")  # noqa: SIM115 - held for the process's life
        self.proc = subprocess.Popen(argv, cwd=cwd, env=dict(env), stdin=subprocess.DEVNULL,
                                     stdout=self._log, stderr=subprocess.STDOUT, start_new_session=True)

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    def tail(self, n: int = 30) -> str:
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(lines[-n:])

    def stop(self) -> None:
        if self.proc.poll() is None:
            try:  # its own session: the kill reaches any child it started, nothing of ours
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.proc.wait(timeout=10)
        self._log.close()
        if not self.keep_dir:
            shutil.rmtree(self.cwd, ignore_errors=True)

    def __enter__(self) -> AutopilotProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


# -- ArduPilot ---------------------------------------------------------------------------
#: what our airframe needs on top of the tree's copter.parm (whose FRAME_TYPE 0 is a plus
#: frame): quad X, the hover throttle of sim.vehicle.motor_quad's default airframe, its thrust
#: curve. MOT_THST_HOVER is a start: MOT_HOVER_LEARN (default 2) refines it in flight.
ARDUPILOT_PARAMS: dict[str, float] = {
    "FRAME_CLASS": 1,  # quad
    "FRAME_TYPE": 1,  # X
    "MOT_THST_EXPO": 0.65,
    "MOT_THST_HOVER": 0.41,
}


@dataclass(frozen=True)
class ArduPilotLaunch:
    binary: Path
    instance: int
    home: HomePosition
    #: MAVLink on SERIAL0 sent over UDP to this port on 127.0.0.1 (the companion's udpin port)
    api_port: int
    gcs_port: int | None = None  # SERIAL1 over UDP to a ground station; None: SERIAL1 stays TCP 5762+10*I
    heading_deg: float = 0.0
    speedup: float = 1.0
    params: Mapping[str, float] = field(default_factory=dict)
    defaults: Path | None = None  # copter.parm; None: from the binary's tree
    keep_dir: bool = False

    def __post_init__(self) -> None:
        if not 0 <= self.instance <= 99:
            raise ValueError(f"ArduPilot instance must be in 0..99 (got {self.instance})")
        if not self.speedup > 0:
            raise ValueError(f"ArduPilot speedup must be > 0 (got {self.speedup})")

    @property
    def copter_parm(self) -> Path:
        if self.defaults is not None:
            return self.defaults
        # BIN = TREE/build/sitl/bin/arducopter
        return self.binary.parents[3] / "Tools" / "autotest" / "default_params" / "copter.parm"


def start_ardupilot(launch: ArduPilotLaunch) -> AutopilotProcess:
    """ArduCopter on our JSON physics (sim.bridges.ardupilot_json, UDP 9002+10*I), in a fresh
    working directory (its eeprom.bin and logs stay there)."""
    parm = launch.copter_parm
    if not parm.is_file():
        raise AutopilotStartError(f"ArduPilot defaults {parm} not found (the tree's "
                                  "Tools/autotest/default_params/copter.parm; pass defaults=)")
    cwd = Path(tempfile.mkdtemp(prefix=f"ardupilot-{launch.instance}-"))
    ours = cwd / "uavsearch.parm"
    params = {**ARDUPILOT_PARAMS, "SYSID_THISMAV": launch.instance + 1, **launch.params}
    ours.write_text("".join(f"{k} {v:g}\n" for k, v in params.items()))
    h = launch.home
    argv = [str(launch.binary), "-S", "--model", "JSON:127.0.0.1", "--speedup", f"{launch.speedup:g}",
            "-I", str(launch.instance), "--home", f"{h.lat_deg:.8f},{h.lon_deg:.8f},{h.alt_m:.2f},{launch.heading_deg:g}",
            "--defaults", f"{parm},{ours}", "--serial0", f"udpclient:127.0.0.1:{launch.api_port}"]
    if launch.gcs_port is not None:
        argv += ["--serial1", f"udpclient:127.0.0.1:{launch.gcs_port}"]
    return AutopilotProcess(argv, cwd, os.environ, launch.keep_dir)


# -- PX4 ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Px4Launch:
    binary: Path  # BUILD/bin/px4; its startup files are BUILD/etc
    instance: int
    home: HomePosition
    autostart: int = 10016  # "none_iris": simulator_mavlink, TCP client to 4560+i
    speedup: float = 1.0  # PX4_SIM_SPEED_FACTOR: rcS scales its link-loss timeouts by it
    params: Mapping[str, float] = field(default_factory=dict)
    keep_dir: bool = False

    def __post_init__(self) -> None:
        if not 0 <= self.instance <= 99:
            raise ValueError(f"PX4 instance must be in 0..99 (got {self.instance})")

    @property
    def etc(self) -> Path:
        return self.binary.parent.parent / "etc"


def px4_ports(instance: int) -> dict[str, int]:
    """PX4 SITL's ports for instance i (ROMFS init.d-posix px4-rc.mavlink, px4-rc.mavlinksim):
    the onboard link sends to 14540+i (14549 for every i > 9), listens on 14580+i."""
    return {"simulator_tcp": 4560 + instance, "onboard_local": 14580 + instance,
            "onboard_remote": 14540 + instance if instance <= 9 else 14549,
            "gcs_local": 18570 + instance, "gcs_remote": 14550}


def start_px4(launch: Px4Launch) -> AutopilotProcess:
    """PX4 on our simulator_mavlink world (sim.bridges.px4_hil, which must already listen on TCP
    4560+i), in a fresh working directory (parameters.bson, logs) linked to BUILD/etc."""
    if not (launch.etc / "init.d-posix" / "rcS").is_file():
        raise AutopilotStartError(f"PX4 startup files not found in {launch.etc} (the build dir's etc/)")
    cwd = Path(tempfile.mkdtemp(prefix=f"px4-{launch.instance}-"))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PX4_SIMULATOR", "PX4_SIM_MODEL", "PX4_PARAM_"))}
    env.update(PX4_SYS_AUTOSTART=str(launch.autostart), PX4_HOME_LAT=f"{launch.home.lat_deg:.8f}",
               PX4_HOME_LON=f"{launch.home.lon_deg:.8f}", PX4_HOME_ALT=f"{launch.home.alt_m:.2f}",
               PX4_SIM_SPEED_FACTOR=f"{launch.speedup:g}")
    for name, value in launch.params.items():
        env[f"PX4_PARAM_{name}"] = f"{value:g}" if isinstance(value, float) else str(value)
    argv = [str(launch.binary), "-d", "-i", str(launch.instance), "-w", str(cwd), str(launch.etc)]
    return AutopilotProcess(argv, cwd, env, launch.keep_dir)


def wait_alive(proc: AutopilotProcess, seconds: float) -> None:
    """Raise with the log's tail if the binary exits within `seconds`."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not proc.alive:
            raise AutopilotStartError(f"{proc.argv[0]} exited ({proc.proc.returncode}):\n{proc.tail()}")
        time.sleep(0.05)
