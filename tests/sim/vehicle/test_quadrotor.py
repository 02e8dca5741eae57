import numpy as np
import pytest

from sim.vehicle import KinematicVehicle, PyBulletQuadrotor


@pytest.fixture
def quad():
    q = PyBulletQuadrotor()
    yield q
    q.close()


def _fly(q, seconds: float, dt: float = 0.1):
    out = []
    for _ in range(int(seconds / dt)):
        q.step(dt)
        out.append((q.state.position_ned.copy(), q.state.velocity_ned.copy()))
    return out


def test_takeoff_and_hold(quad) -> None:
    assert quad.state.landed and not quad.state.armed
    assert quad.arm()
    quad.set_position_target(np.array([0.0, 0.0, -3.5]))
    _fly(quad, 6.0)
    track = _fly(quad, 3.0)
    alt = np.array([-p[2] for p, _ in track])
    assert np.all(np.abs(alt - 3.5) < 0.2), "holds 3.5 m within 0.2 m"
    assert not quad.state.landed
    hover = quad.motor_thrusts.sum()
    assert abs(hover - 1.5 * 9.81) < 0.1 * 1.5 * 9.81, "hover thrust carries the weight"
    assert not quad.disarm(), "refuses to disarm in flight"


def test_position_target_with_speed_limit_then_land(quad) -> None:
    quad.arm()
    quad.set_position_target(np.array([0.0, 0.0, -3.5]))
    _fly(quad, 5.0)
    quad.set_position_target(np.array([6.0, 8.0, -3.5]), speed=2.5)
    track = _fly(quad, 12.0)
    vmax = max(np.linalg.norm(v[:2]) for _, v in track)
    assert vmax <= 2.5 * 1.1
    assert np.linalg.norm(quad.state.position_ned[:2] - [6.0, 8.0]) < 0.3
    quad.land()
    _fly(quad, 12.0)
    assert quad.state.landed and not quad.state.armed, "lands and disarms on touchdown"
    assert np.linalg.norm(quad.state.position_ned[:2] - [6.0, 8.0]) < 0.5


def test_kinematic_vehicle_honours_the_same_contract() -> None:
    k = KinematicVehicle(max_speed=3.0)
    k.arm()
    k.set_position_target(np.array([10.0, 0.0, -3.5]), speed=2.0)
    for _ in range(200):
        k.step(0.05)
    assert np.allclose(k.state.position_ned, [10, 0, -3.5], atol=0.05)
    k.land()
    for _ in range(200):
        k.step(0.05)
    assert k.state.landed and not k.state.armed
