"""Fleets step many vehicles with numpy over the vehicle axis and fly what the lone models fly."""

import numpy as np
import pytest

from sim.vehicle import KinematicVehicle, PyBulletQuadrotor
from sim.vehicle.fleet import KinematicFleet, QuadrotorFleet

LEGS = {  # per vehicle: (seconds, command name, args, kwargs)
    0: [(4.0, "set_position_target", ([0.0, 0.0, -3.5],), {}),
        (5.0, "set_position_target", ([6.0, 8.0, -3.5],), {"yaw": 1.0, "speed": 2.5}),
        (3.0, "set_velocity_target", ([1.0, -0.5, 0.2],), {}),
        (8.0, "land", (), {})],
    1: [(3.0, "set_position_target", ([0.0, 0.0, -2.0],), {}),
        (6.0, "set_position_target", ([-5.0, 3.0, -6.0],), {"yaw": -2.0}),
        (11.0, "land", (), {})],
}


def _fly(models: dict, step) -> dict[int, np.ndarray]:
    """Fly LEGS on models {index: FlightModel}; `step(dt)` advances all of them."""
    for m in models.values():
        assert m.arm()
    out: dict[int, list] = {i: [] for i in models}
    plans = {i: [(t, name, a, kw) for t, name, a, kw in LEGS[i]] for i in models}
    t, starts = 0.0, {i: 0.0 for i in models}
    for i in models:
        _, name, a, kw = plans[i][0]
        getattr(models[i], name)(*[np.array(x) for x in a], **kw)
    while t < 20.0 - 1e-9:
        step(0.02)
        t += 0.02
        for i, m in models.items():
            s = m.state
            out[i].append(np.r_[s.position_ned, s.velocity_ned, s.attitude_rpy, float(s.armed)])
            if plans[i] and t - starts[i] >= plans[i][0][0] - 1e-9:
                plans[i].pop(0)
                starts[i] = t
                if plans[i]:
                    _, name, a, kw = plans[i][0]
                    getattr(m, name)(*[np.array(x) for x in a], **kw)
    return {i: np.array(v) for i, v in out.items()}


def test_quadrotor_fleet_flies_what_lone_quadrotors_fly() -> None:
    fleet = QuadrotorFleet(3)  # the third stays on the ground, disarmed
    got = _fly({0: fleet.members[0], 1: fleet.members[1]}, fleet.step)
    assert fleet.members[2].state.landed and not fleet.members[2].state.armed
    assert np.allclose(fleet.members[2].state.position_ned, 0.0, atol=1e-3), "an idle vehicle stays put"
    fleet.close()
    for i in (0, 1):
        q = PyBulletQuadrotor()
        want = _fly({i: q}, q.step)[i]
        q.close()
        assert np.ptp(want[:, 2]) > 1.5 and want[-1, 9] == 0.0, "flies up, lands and disarms"
        # vehicles at other offsets in a shared world: equal up to float rounding
        assert np.abs(got[i] - want).max() < 1e-5, i


def test_kinematic_fleet_flies_what_lone_kinematic_vehicles_fly() -> None:
    fleet = KinematicFleet(2)
    got = _fly(dict(enumerate(fleet.members)), fleet.step)
    for i in (0, 1):
        k = KinematicVehicle()
        want = _fly({i: k}, k.step)[i]
        assert want[-1, 9] == 0.0 and np.ptp(want[:, 2]) > 1.5
        np.testing.assert_allclose(got[i], want, atol=1e-9)


def test_a_member_is_stepped_by_its_fleet_only() -> None:
    fleet = KinematicFleet(1)
    with pytest.raises(RuntimeError, match="fleet.step"):
        fleet.members[0].step(0.02)
    with pytest.raises(ValueError, match="at least one"):
        KinematicFleet(0)


@pytest.mark.parametrize("free_flight", [False, True])
def test_the_fleet_reads_the_rotations_pybullet_gives(free_flight: bool) -> None:
    """QuadrotorFleet turns the bodies' quaternions into rotations itself (one numpy pass, not a
    getMatrixFromQuaternion call per body per substep): the same numbers, tilted and yawed.
    Vehicles in free flight (numpy step) hold Bullet's m_baseQuat q instead: their rotation is
    M(q)^T, the matrix PyBullet makes of conj(q) (what it reports is that, through a matrix)."""
    import pybullet as p

    from sim.vehicle.free_flight import matrices

    fleet = QuadrotorFleet(4, free_flight=free_flight, free_flight_min=1)  # 4 alone would stay in PyBullet
    try:
        for i, m in enumerate(fleet.members):
            m.arm()
            m.set_position_target(np.array([3.0 * i, -2.0, -3.0]), yaw=0.7 * i)
        for _ in range(100):
            fleet.step(0.02)
        rot = fleet.rotations
        assert fleet.free.all() == free_flight, "at 3 m every vehicle flies free, or none does"
        for i, (b, r) in enumerate(zip(fleet.bodies, rot, strict=True)):
            if free_flight:  # no PyBullet body while free: M(q)^T is PyBullet's matrix of conj(q)
                x, y, z, w = fleet._q[:, i]
                assert b is None
                assert np.array_equal(r, matrices(fleet._q[:, i:i + 1])[:, 0].reshape(3, 3).T)
                assert np.array_equal(r.ravel(), np.array(p.getMatrixFromQuaternion((-x, -y, -z, w))))
            else:
                _, quat = p.getBasePositionAndOrientation(b, fleet.cid)
                assert np.array_equal(r.ravel(), np.array(p.getMatrixFromQuaternion(quat)))
        assert np.abs(rot[:, 2, :2]).max() > 0.01, "tilted: the test saw more than the identity"
    finally:
        fleet.close()
