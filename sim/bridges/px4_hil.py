"""PX4's simulator interface (simulator_mavlink), served by our motor-driven PyBullet body.

PX4 started with a non-SIH airframe (PX4_SYS_AUTOSTART=10016, "none_iris") connects as a TCP
client to 4560+i (ROMFS init.d-posix px4-rc.mavlinksim; src/modules/simulation/
simulator_mavlink/SimulatorMavlink.cpp). Over that stream, MAVLink 2:
  - we send HIL_SENSOR every step (250 Hz, PX4's IMU_INTEG_RATE in SITL): its time_usec *sets
    PX4's clock* (px4_clock_settime: lockstep), accel (specific force, FRD), gyro, mag (gauss,
    body), abs_pressure (hPa), pressure_alt, temperature, fields_updated; and HIL_GPS at
    GpsConfig.rate_hz (fix, lat/lon 1e7, alt mm, velocity cm/s, eph/epv cm);
  - PX4 answers each sensor step with HIL_ACTUATOR_CONTROLS once its control loop runs:
    controls[0..3] the motors 0..1 in iris order (CA_ROTOR0..3: front-right CCW, back-left
    CCW, front-left CW, back-right CW: sim.vehicle.motor_quad's order), mode bit 128 armed.
Lockstep here: send HIL_SENSOR(t), wait for the controls it produced (until PX4 sends its
first controls, and at most `lockstep_timeout_s` of wall time after, time runs on without),
step the body by dt, t += dt.

PX4 checks its sensors for stale data (the same value many samples running marks a sensor
failed): every sensor here carries a little seeded white noise.
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from sim.mavlink.runner import BackgroundRunner
from sim.vehicle.geo import HomePosition
from sim.vehicle.gps import GpsConfig, GpsModel
from sim.vehicle.motor_quad import MotorQuadrotor

#: HIL_SENSOR fields_updated bits PX4 reads (SimulatorMavlink.hpp SensorSource): accel xyz,
#: gyro xyz, mag xyz, abs pressure, pressure altitude, temperature
FIELDS_ACCEL = 0b111
FIELDS_GYRO = 0b111 << 3
FIELDS_MAG = 0b111 << 6
FIELDS_BARO = (1 << 9) | (1 << 11) | (1 << 12)
FIELDS_ALL = FIELDS_ACCEL | FIELDS_GYRO | FIELDS_MAG | FIELDS_BARO
ARMED_FLAG = 128  # MAV_MODE_FLAG_SAFETY_ARMED in HIL_ACTUATOR_CONTROLS.mode


def simulator_port(instance: int) -> int:
    return 4560 + instance


@dataclass(frozen=True)
class EarthField:
    """The world's magnetic field at home. Defaults: PX4's own WMM tables
    (src/lib/world_magnetic_model/geo_magnetic_tables.hpp, bilinear as geo_mag_declination.cpp)
    at lat 51.4545, lon -2.5879 (our default field): what PX4 compares the magnetometer with.
    Elsewhere PX4 is told our declination (EKF2_DECL_TYPE 0, EKF2_MAG_DECL) and does not
    check the strength or inclination (COM_ARM_MAG_STR 0, EKF2_MAG_CHECK 0): see px4_params."""

    declination_deg: float = -0.0267
    inclination_deg: float = 66.23
    strength_gauss: float = 0.4895

    def ned(self) -> np.ndarray:
        d, i = math.radians(self.declination_deg), math.radians(self.inclination_deg)
        b = self.strength_gauss
        return np.array([b * math.cos(i) * math.cos(d), b * math.cos(i) * math.sin(d), b * math.sin(i)])


def px4_params(field: EarthField) -> dict[str, float]:
    """What PX4 needs to fly our body: the magnetic field we simulate (wherever home is), GPS
    checks our receiver passes, and the airframe's rotor geometry and yaw moment (sim.vehicle.quadrotor.Airframe: arm 0.25 m,
    km/kf = 0.0167 m) rather than the iris's."""
    d = 0.25 / math.sqrt(2)
    km = 2.0e-7 / 1.2e-5
    params: dict[str, float] = {"EKF2_DECL_TYPE": 0, "EKF2_MAG_DECL": field.declination_deg,
                                "COM_ARM_MAG_STR": 0, "EKF2_MAG_CHECK": 0,
                                # our receiver's white noise (0.6 m a fix, sim.vehicle.gps) reads
                                # as drift to the on-ground drift checks (bits 5-8): off
                                "EKF2_GPS_CHECK": 2047 & ~(0b1111 << 5),
                                # height on the barometer alone (GNSS aiding: lon/lat and 3D
                                # velocity, not altitude; default 7 fuses it too): our receiver's
                                # vertical error (1 m white, a 1 m drifting bias) pulled EKF2's
                                # height 1-2.7 m off over a flight (measured: the camera flew at
                                # 4.6-6.2 m for 3.5 m, its footprint 30-80 % wider than the companion
                                # thought, and 4 of 5 cows were mapped to the wrong cells). As
                                # sim.vehicle.gps models the autopilot (EKF2_HGT_REF baro) and as
                                # an operator flying a camera at 3.5 m configures it
                                "EKF2_GPS_CTRL": 0b101,
                                # ... and the barometer its height reference (default 1, GNSS:
                                # then the GNSS altitude still sets the baro's bias, and the
                                # camera flew 2.5-3.4 m for 3.5 m; measured, seed 6)
                                "EKF2_HGT_REF": 0}
    for i, (x, y, spin) in enumerate(((d, d, 1), (-d, -d, 1), (d, -d, -1), (-d, d, -1))):  # FRD
        params.update({f"CA_ROTOR{i}_PX": round(x, 4), f"CA_ROTOR{i}_PY": round(y, 4),
                       f"CA_ROTOR{i}_KM": round(spin * km, 4)})
    return params


def isa_pressure_hpa(alt_amsl_m: float) -> float:
    """The International Standard Atmosphere's pressure at an altitude (PX4's inverse)."""
    return 1013.25 * (1.0 - 2.25577e-5 * alt_amsl_m) ** 5.25588


@dataclass(frozen=True)
class SensorNoise:
    accel: float = 0.02  # m/s^2
    gyro: float = 0.002  # rad/s
    mag: float = 0.001  # gauss
    baro_m: float = 0.05  # m of altitude


def hil_sensor(time_usec: int, accel, gyro, mag, pressure_alt_m: float) -> mavlink.MAVLink_hil_sensor_message:
    """One HIL_SENSOR: accel/gyro/mag body FRD; pressure and temperature of the ISA at that
    altitude; every field marked updated."""
    return mavlink.MAVLink_hil_sensor_message(
        time_usec, float(accel[0]), float(accel[1]), float(accel[2]), float(gyro[0]), float(gyro[1]), float(gyro[2]),
        float(mag[0]), float(mag[1]), float(mag[2]), isa_pressure_hpa(pressure_alt_m), 0.0, pressure_alt_m,
        15.0 - 0.0065 * pressure_alt_m, FIELDS_ALL, 0)


def hil_gps(time_usec: int, fix) -> mavlink.MAVLink_hil_gps_message:
    """One HIL_GPS from a sim.vehicle.gps fix."""
    vn, ve, vd = (float(x) for x in fix.vel_ned)
    cog = int(round(math.degrees(math.atan2(ve, vn)) % 360 * 100)) if math.hypot(vn, ve) > 0.2 else 65535
    return mavlink.MAVLink_hil_gps_message(
        time_usec, fix.fix_type, int(round(fix.lat_deg * 1e7)), int(round(fix.lon_deg * 1e7)),
        int(round(fix.alt_m * 1000)), int(round(fix.eph_m * 100)), int(round(fix.epv_m * 100)),
        int(round(math.hypot(vn, ve) * 100)), int(round(vn * 100)), int(round(ve * 100)), int(round(vd * 100)),
        cog, fix.satellites_visible, 0, 0)


class Px4HilBridge(BackgroundRunner):
    """Serve one PX4's physics on TCP `port` (simulator_port(instance)). Listens at once (PX4
    retries its connect every 0.5 ms until we do); run() accepts, then steps in lockstep.

    t: simulated seconds sent last; PX4's clock (hrt_absolute_time, time_boot_ms) is
    t * 1e6 us + time_offset_usec: HIL_SENSOR.time_usec = round((t + t0) * 1e6)."""

    def __init__(self, body: MotorQuadrotor, port: int, home: HomePosition, seed: int = 0,
                 gps: GpsConfig | None = None, field: EarthField | None = None, noise: SensorNoise | None = None,
                 dt: float = 0.004, speedup: float = 1.0, lockstep_timeout_s: float = 1.0,
                 on_step: Callable[[float], None] | None = None, host: str = "127.0.0.1",
                 lock: threading.Lock | None = None) -> None:
        """lock: held while the body steps and is read (a camera rendering the same PyBullet
        world takes it too: PyBullet is not thread-safe)."""
        if not speedup >= 0:
            raise ValueError(f"speedup must be >= 0 (0: as fast as possible; got {speedup})")
        if not 0.0005 <= dt <= 0.02:
            raise ValueError(f"dt must be in 0.5..20 ms (got {dt})")
        self.body, self.home, self.dt, self.speedup = body, home, dt, speedup
        self.lockstep_timeout_s = lockstep_timeout_s
        self.on_step = on_step
        self.lock = lock or threading.Lock()
        self.gps = GpsModel(home, seed, gps or GpsConfig())
        self.mag_ned = (field or EarthField()).ned()
        self.noise = noise or SensorNoise()
        self.rng = np.random.default_rng([seed, 0x4A11])  # the IMU's, mag's and baro's noise
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=51)  # the simulator's ids
        self.mav.robust_parsing = True
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind((host, port))
        self.server.listen(1)
        self.port = port
        self.conn: socket.socket | None = None
        #: PX4's clock starts at this (its clock must not start at 0: some modules treat a
        #: timestamp of 0 as "never")
        self.time_offset_usec = 1_000_000
        self.t = 0.0
        self.steps = 0
        self.controls_received = 0
        self.lockstep_timeouts = 0
        self.armed = False
        self.controls = (0.0, 0.0, 0.0, 0.0)
        self._got_controls = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def time_usec(self) -> int:
        return int(round(self.t * 1e6)) + self.time_offset_usec

    def _send(self, msg: mavlink.MAVLink_message) -> None:
        assert self.conn is not None
        self.conn.sendall(msg.pack(self.mav))

    def _read(self, timeout: float) -> bool:
        """Read what PX4 sent within timeout; True when a HIL_ACTUATOR_CONTROLS came."""
        assert self.conn is not None
        ready, _, _ = select.select([self.conn], [], [], timeout)
        if not ready:
            return False
        data = self.conn.recv(65536)
        if not data:
            raise ConnectionError("PX4 closed the simulator connection")
        got = False
        for msg in self.mav.parse_buffer(data) or []:
            if msg.get_type() == "HIL_ACTUATOR_CONTROLS":
                self.controls = tuple(msg.controls[:4])
                self.armed = bool(msg.mode & ARMED_FLAG)
                self.controls_received += 1
                self._got_controls = got = True
        return got

    def send_sensors(self) -> None:
        """HIL_SENSOR for now (and HIL_GPS when a fix is due), from the body's state."""
        s, imu, n = self.body.state, self.body.imu, self.noise
        z = self.rng.standard_normal(10)
        accel = np.asarray(imu.accel) + n.accel * z[0:3]
        gyro = np.asarray(imu.gyro) + n.gyro * z[3:6]
        mag = self.body.attitude_dcm.T @ self.mag_ned + n.mag * z[6:9]
        # the barometer's slow drift (the receiver model's Gauss-Markov, updated at each fix:
        # what sim.vehicle.gps says an autopilot holding height on it is off by) and white noise
        alt = self.home.alt_m - float(s.position_ned[2]) - self.gps.baro + n.baro_m * float(z[9])
        usec = self.time_usec
        self._send(hil_sensor(usec, accel, gyro, mag, alt))
        fix = self.gps.sample(self.t, s.position_ned, s.velocity_ned)
        if fix is not None:
            self._send(hil_gps(usec, fix))

    def accept(self, timeout: float | None = None) -> bool:
        ready, _, _ = select.select([self.server], [], [], timeout)
        if not ready:
            return False
        self.conn, _ = self.server.accept()
        self.conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return True

    def step(self) -> None:
        """One lockstep step: sensors out, PX4's controls in, the body moved on by dt."""
        with self.lock:
            self.send_sensors()
        wait_end = time.monotonic() + self.lockstep_timeout_s
        while True:
            if self._read(0.0 if not self._got_controls else max(0.0, wait_end - time.monotonic())):
                break
            if not self._got_controls or time.monotonic() >= wait_end:
                if self._got_controls:
                    self.lockstep_timeouts += 1
                break
        if not self._got_controls:
            time.sleep(0.001)  # PX4 starting up: give it the CPU
        with self.lock:
            self.body.set_throttle(self.controls if self.armed else (0.0, 0.0, 0.0, 0.0))
            self.body.step(self.dt)
            self.t += self.dt
            self.steps += 1
            if self.on_step is not None:
                self.on_step(self.t)

    def run(self, duration: float | None = None) -> None:
        while self.conn is None and not self._stop.is_set():
            self.accept(0.1)
        wall0 = time.monotonic()
        while not self._stop.is_set() and (duration is None or self.t < duration):
            try:
                self.step()
            except (ConnectionError, OSError):
                if self._stop.is_set():
                    return
                raise
            if self.speedup > 0:
                lag = wall0 + self.t / self.speedup - time.monotonic()
                if lag > 0:
                    time.sleep(lag)

    def _thread_name(self) -> str:
        return f"px4-hil-{self.port}"

    def _close(self) -> None:
        if self.conn is not None:
            self.conn.close()
        self.server.close()
