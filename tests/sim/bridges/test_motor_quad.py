"""The motor-driven body an autopilot flies: it hovers at its hover throttle, its IMU reads what
an accelerometer and a gyro would, and each motor pushes the way the autopilots' quad-X
layout says (motor 1 front-right CCW, 2 back-left CCW, 3 front-left CW, 4 back-right CW)."""

import numpy as np
import pytest

from sim.vehicle.motor_quad import MotorModel, MotorQuadrotor, dcm_to_quaternion, hover_throttle


@pytest.fixture
def body():
    b = MotorQuadrotor(start_ned=(0.0, 0.0, -10.0))  # in the air: no ground in the way
    yield b
    b.close()


def _fly(b: MotorQuadrotor, u, seconds: float, dt: float = 1 / 400) -> None:
    for _ in range(int(round(seconds / dt))):
        b.set_throttle(u)
        b.step(dt)


def test_hover_throttle_is_plausible_and_holds_height(body: MotorQuadrotor) -> None:
    u = hover_throttle(body.af, body.motors)
    assert 0.3 < u < 0.5
    e = body.motors.thrust_expo
    body.omega = [body.af.max_omega * np.sqrt((1 - e) * u + e * u * u)] * 4  # rotors already at speed
    z0 = body.state.position_ned[2]
    _fly(body, [u] * 4, 1.0)
    assert abs(body.state.velocity_ned[2]) < 0.05 and abs(body.state.position_ned[2] - z0) < 0.05
    np.testing.assert_allclose(body.imu.accel, [0, 0, -9.81], atol=0.02)  # hover: thrust = weight
    assert hover_throttle(body.af, MotorModel(thrust_expo=0.0)) == pytest.approx(
        body.af.mass * 9.81 / (4 * body.af.kf * body.af.max_omega ** 2))


def test_imu_at_rest_reads_the_ground_reaction() -> None:
    b = MotorQuadrotor()
    try:
        _fly(b, [0.0] * 4, 0.5)
        np.testing.assert_allclose(b.imu.accel, [0, 0, -9.81], atol=1e-3)
        np.testing.assert_allclose(b.imu.gyro, [0, 0, 0], atol=1e-6)
        assert b.quaternion == pytest.approx((1, 0, 0, 0), abs=1e-5)  # nose north, level: FRD = NED
        np.testing.assert_allclose(b.state.position_ned, [0, 0, 0], atol=1e-3)
    finally:
        b.close()


@pytest.mark.parametrize(("delta", "axis", "sign"), [
    ((1, 1, -1, -1), 2, +1),  # CCW motors faster: the body yaws clockwise seen from above (+r, FRD)
    ((-1, 1, 1, -1), 0, +1),  # left motors (2, 3) faster: roll right (+p)
    ((1, -1, 1, -1), 1, +1),  # front motors (1, 3) faster: nose up (+q)
])
def test_each_motor_pushes_the_quad_x_way(body: MotorQuadrotor, delta, axis: int, sign: int) -> None:
    u = hover_throttle(body.af, body.motors)
    _fly(body, [u + 0.03 * d for d in delta], 0.1)
    rates = np.asarray(body.imu.gyro)
    assert sign * rates[axis] > 0.03 and np.all(np.abs(np.delete(rates, axis)) < 0.1 * abs(rates[axis])), rates


def test_attitude_quaternion_matches_the_dcm_and_euler(body: MotorQuadrotor) -> None:
    u = hover_throttle(body.af, body.motors)
    _fly(body, [u + 0.02, u - 0.01, u + 0.01, u - 0.02], 0.3)
    r = body.attitude_dcm
    w, x, y, z = body.quaternion
    q = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    np.testing.assert_allclose(q, r, atol=1e-9)
    roll, pitch, yaw = body.state.attitude_rpy
    assert np.arctan2(r[2, 1], r[2, 2]) == pytest.approx(roll, abs=1e-6)
    assert -np.arcsin(r[2, 0]) == pytest.approx(pitch, abs=1e-6)
    assert np.arctan2(r[1, 0], r[0, 0]) == pytest.approx(yaw, abs=1e-6)
    for angle in (0.1, 2.0, np.pi - 1e-3):  # Shepperd's branches
        c, s = np.cos(angle), np.sin(angle)
        for m in (np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])):
            qq = dcm_to_quaternion(m)
            assert np.linalg.norm(qq) == pytest.approx(1.0) and qq[0] >= 0


def test_bad_commands_and_steps_say_what_is_wrong(body: MotorQuadrotor) -> None:
    with pytest.raises(ValueError, match="4 motor commands"):
        body.set_throttle([0.5] * 3)
    with pytest.raises(ValueError, match="dt > 0"):
        body.step(0.0)
    with pytest.raises(ValueError, match="thrust_expo"):
        MotorModel(thrust_expo=1.5)
    with pytest.raises(NotImplementedError, match="autopilot flies it"):
        body.set_position_target(np.zeros(3))
    body.set_throttle([float("nan"), 2.0, -1.0, 0.5])
    assert body._throttle == (0.0, 1.0, 0.0, 0.5)
