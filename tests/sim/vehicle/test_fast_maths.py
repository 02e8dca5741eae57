"""The float controller and force summation (issue 13) fly the same trajectories as the
original numpy maths, kept in reference_quadrotor.py."""

import numpy as np
import pytest
from reference_quadrotor import ReferenceController, ReferenceQuadrotor

from sim.vehicle import PyBulletQuadrotor
from sim.vehicle.controller import BatchController, CascadedController


def _fly(q) -> np.ndarray:
    """Take off, fly a speed-limited leg with a yaw, a velocity leg, a climb with the opposite
    yaw, then land: every mode the controller has. (steps, 10) state samples."""
    legs = [
        (4.0, lambda: q.set_position_target(np.array([0.0, 0.0, -3.5]))),
        (6.0, lambda: q.set_position_target(np.array([6.0, 8.0, -3.5]), yaw=1.0, speed=2.5)),
        (3.0, lambda: q.set_velocity_target(np.array([1.0, -0.5, 0.2]))),
        (3.0, lambda: q.set_position_target(np.array([2.0, 2.0, -5.0]), yaw=-2.5)),
        (9.0, q.land),
    ]
    assert q.arm()
    out = []
    for seconds, command in legs:
        command()
        for _ in range(int(seconds / 0.02)):
            q.step(0.02)
            s = q.state
            out.append(np.r_[s.position_ned, s.velocity_ned, s.attitude_rpy, float(s.armed)])
    q.close()
    return np.array(out)


def test_fast_quadrotor_flies_the_reference_trajectory() -> None:
    ref, new = _fly(ReferenceQuadrotor()), _fly(PyBulletQuadrotor())
    assert np.ptp(ref[:, 0]) > 5 and np.ptp(ref[:, 2]) > 4, "the flight goes somewhere"
    assert ref[-1, 9] == 0.0 and new[-1, 9] == 0.0, "both land and disarm"
    # same maths up to float rounding: positions within a micrometre over 25 s of flight
    assert np.abs(ref - new).max() < 1e-6


@pytest.mark.parametrize("seed", [0, 1])
def test_float_and_batched_controllers_match_the_reference_on_random_states(seed: int) -> None:
    """Random attitudes, rates and setpoints (tilted, inverted, saturating): the same outputs."""
    rng = np.random.default_rng(seed)
    n = 64
    J = np.diag([0.016, 0.016, 0.031])
    batch = BatchController(n, 1.5, J)
    refs = [ReferenceController(1.5, J) for _ in range(n)]
    fasts = [CascadedController(1.5, J) for _ in range(n)]
    for _ in range(5):  # several calls, so the integrators carry state
        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        rot = np.array([_quat_to_rot(x) for x in q])
        pos, target = rng.normal(0, 5, (n, 3)), rng.normal(0, 5, (n, 3))
        vel, w = rng.normal(0, 2, (n, 3)), rng.normal(0, 3, (n, 3))
        speed = np.where(rng.random(n) < 0.5, rng.uniform(0.5, 8, n), np.nan)
        yaw = rng.uniform(-np.pi, np.pi, n)
        vsp_b = batch.velocity_setpoint(pos, target, speed)
        thr_b, tq_b = batch.thrust_and_torque(rot, vel, w, vsp_b, yaw, 1 / 240)
        for i in range(n):
            sp = None if np.isnan(speed[i]) else float(speed[i])
            vsp_r = refs[i].velocity_setpoint(pos[i], target[i], sp)
            vsp_f = fasts[i].velocity_setpoint(pos[i], target[i], sp)
            thr_r, tq_r = refs[i].thrust_and_torque(rot[i], vel[i], w[i], vsp_r, yaw[i], 1 / 240)
            thr_f, tq_f = fasts[i].thrust_and_torque(tuple(rot[i].ravel()), vel[i], w[i], vsp_f, yaw[i], 1 / 240)
            np.testing.assert_allclose(vsp_f, vsp_r, atol=1e-12)
            np.testing.assert_allclose(vsp_b[i], vsp_r, atol=1e-12)
            np.testing.assert_allclose([thr_f, *tq_f], [thr_r, *tq_r], atol=1e-9)
            np.testing.assert_allclose([thr_b[i], *tq_b[i]], [thr_r, *tq_r], atol=1e-9)


def _quat_to_rot(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
