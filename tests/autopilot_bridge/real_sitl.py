"""The real autopilots' own SITLs, for the tests that check our dialects against them.

PX4 flies its built-in SIH physics, ArduCopter its built-in `+` frame; both are started where
PX4_SITL / ARDUPILOT_SITL name their binaries (../shared/peers/build_*.sh build them) and the
tests that use them skip otherwise. Facts about starting them are in those scripts' headers.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

HOME = (51.4545, -2.5879, 30.0)


def binary(var: str) -> Path:
    """The binary an environment variable names, or skip the test saying so."""
    path = os.environ.get(var)
    if not path:
        pytest.skip(f"{var} is not set (a real autopilot SITL binary: see ../shared/peers/build_*.sh)")
    if not Path(path).is_file():
        pytest.skip(f"{var}={path} is not a file")
    return Path(path)


@contextmanager
def px4_sih(instance: int, speed: float = 5.0) -> Iterator[int]:
    """PX4 SITL with its SIH quadrotor as instance `instance` (0-9: from 10 on its onboard link
    no longer sends to 14540 + instance, measured: instance 11 sent to 14549); yields the
    companion's UDP port, 14540 + instance."""
    if not 0 <= instance <= 9:
        raise ValueError(f"PX4 SITL instance {instance}: 0-9 keep the 14540 + instance port layout")
    px4 = binary("PX4_SITL")
    build = px4.parent.parent
    rootfs = build / "rootfs" / str(instance)
    shutil.rmtree(rootfs, ignore_errors=True)  # parameters.bson: start from defaults
    env = dict(os.environ, PX4_SYS_AUTOSTART="10040", PX4_SIMULATOR="sihsim", PX4_SIM_MODEL="sihsim_quadx",
               PX4_HOME_LAT=str(HOME[0]), PX4_HOME_LON=str(HOME[1]), PX4_HOME_ALT=str(HOME[2]),
               PX4_SIM_SPEED_FACTOR=str(speed))
    log = tempfile.NamedTemporaryFile("w", prefix=f"px4-{instance}-", suffix=".log", delete=False)
    proc = subprocess.Popen([str(px4), "-d", "-i", str(instance)], cwd=build, env=env, stdout=log,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        yield 14540 + instance
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        log.close()


#: px4-rc.mavlink's port lines -> their offset from base_port in px4_sih_on_ports
_PX4_PORTS = {"udp_gcs_port_local": 1, "udp_offboard_port_local": 2, "udp_offboard_port_remote": 3,
              "udp_onboard_payload_port_local": 4, "udp_onboard_payload_port_remote": 5,
              "udp_onboard_gimbal_port_local": 6, "udp_onboard_gimbal_port_remote": 7,
              "udp_sihsim_port_local": 8, "udp_sihsim_port_remote": 9}


@contextmanager
def px4_sih_on_ports(base_port: int, speed: float = 5.0, instance: int = 9) -> Iterator[tuple[int, int]]:
    """PX4 SIH as px4_sih, but every UDP port it opens or sends to taken from base_port on
    (base_port .. + 10), so it can run beside other PX4 SITLs: its etc/ is copied to a temporary
    directory with px4-rc.mavlink's ports rewritten (the GCS link sends to base_port, not 14550;
    the XRCE-DDS client to base_port + 10). Yields (companion port, GCS port): the onboard link
    sends to base_port + 3, the GCS link to base_port."""
    import re

    px4 = binary("PX4_SITL")
    work = Path(tempfile.mkdtemp(prefix="px4-ports-"))
    etc = work / "etc"
    shutil.copytree(px4.parent.parent / "etc", etc)
    rc = etc / "init.d-posix" / "px4-rc.mavlink"
    text = rc.read_text()
    for name, k in _PX4_PORTS.items():
        text, n = re.subn(rf"^(\s*){name}=.*$", rf"\g<1>{name}={base_port + k}", text, flags=re.M)
        assert n == 1, f"{name} not found once in {rc}"
    text = text.replace("-r 4000000 -f $mavlink_network_interface_arg", f"-r 4000000 -f -o {base_port} "
                        "$mavlink_network_interface_arg", 1)
    text = re.sub(r"^.*-gt 9 \].*$", "", text, flags=re.M)  # the >9-instance remap of the onboard port
    rc.write_text(text)
    root = work / "root"
    root.mkdir()
    env = dict(os.environ, PX4_SYS_AUTOSTART="10040", PX4_SIMULATOR="sihsim", PX4_SIM_MODEL="sihsim_quadx",
               PX4_HOME_LAT=str(HOME[0]), PX4_HOME_LON=str(HOME[1]), PX4_HOME_ALT=str(HOME[2]),
               PX4_SIM_SPEED_FACTOR=str(speed), PX4_UXRCE_DDS_PORT=str(base_port + 10))
    log = open(work / "px4.log", "w")  # noqa: SIM115 - closed in finally
    proc = subprocess.Popen([str(px4), "-d", "-i", str(instance), "-w", str(root), str(etc)], env=env, stdout=log,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        yield base_port + 3, base_port
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        log.close()
        shutil.rmtree(work, ignore_errors=True)


@contextmanager
def arducopter(instance: int, companion_port: int, speedup: float = 5.0, base_port: int | None = None) -> Iterator[int]:
    """ArduCopter SITL with its own `+` quadrotor physics as instance `instance`, sending its
    MAVLink to UDP companion_port (--serial0 udpclient: it starts at once, no TCP client
    needed); yields that port. Run in a temporary directory (eeprom.bin), wiped (-w).
    base_port: every port it opens from there (its TCP serials at base_port + 2, + 3, RC in, the
    simulator's and IRLock's at + 10 .. + 13) instead of 5760 + 10 x instance and the rest."""
    ap = binary("ARDUPILOT_SITL")
    tree = ap.parents[3]  # .../ardupilot/build/sitl/bin/arducopter -> .../ardupilot
    defaults = tree / "Tools" / "autotest" / "default_params" / "copter.parm"
    work = tempfile.mkdtemp(prefix=f"arducopter-{instance}-")
    ports = [] if base_port is None else [  # before -I, which adds 10 x instance to them
        "--base-port", str(base_port), "--rc-in-port", str(base_port + 10), "--sim-port-in", str(base_port + 11),
        "--sim-port-out", str(base_port + 12), "--irlock-port", str(base_port + 13)]
    cmd = [str(ap), "-S", "-w", "--model", "+", "--speedup", str(speedup), *ports, "-I", str(instance),
           "--home", ",".join(str(v) for v in (*HOME, 0)), "--serial0", f"udpclient:127.0.0.1:{companion_port}"]
    if defaults.is_file():
        cmd += ["--defaults", str(defaults)]
    log = open(Path(work) / "arducopter.log", "w")  # noqa: SIM115 - closed in finally
    proc = subprocess.Popen(cmd, cwd=work, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        yield companion_port
    finally:
        proc.send_signal(signal.SIGKILL)  # it ignores SIGTERM while it waits
        proc.wait(10)
        log.close()
        shutil.rmtree(work, ignore_errors=True)
