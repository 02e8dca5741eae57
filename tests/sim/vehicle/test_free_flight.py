"""free_flight.FreeFlight is Bullet's step of a free body: the same bits as PyBullet's
stepSimulation, step after step, and a fleet flying with it flies what PyBullet flies."""

import numpy as np
import pybullet as p
from test_fleet import _fly

from sim.vehicle.fleet import QuadrotorFleet
from sim.vehicle.free_flight import FreeFlight, body_to_world, matrices


def _world(n: int) -> tuple[int, list[int]]:
    """A PyBullet world as QuadrotorFleet builds it, bodies high above the ground."""
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid)
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.175, 0.175, 0.04], physicsClientId=cid)
    bodies = []
    for i in range(n):
        b = p.createMultiBody(1.5, col, -1, [20.0 * i, 0.0, 500.0], [0, 0, 0, 1], physicsClientId=cid)
        p.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
        bodies.append(b)
    return cid, bodies


def test_the_numpy_step_is_bullets_step_bit_for_bit() -> None:
    """Random orientations, velocities, forces and torques, 600 steps (2.5 s): positions and
    velocities equal to the last bit every step. Bodies 0 and 1 turn slower than 0.001 rad/s
    (Bullet's Taylor branch of the exponential map), body 2 spins at ~20 rad/s; bodies 0 and 1
    feel no torque."""
    n = 6
    cid, bodies = _world(n)
    rng = np.random.default_rng(7)
    info = p.getDynamicsInfo(bodies[0], -1, physicsClientId=cid)
    ff = FreeFlight(info[0], info[2], (0.0, 0.0, -9.81), 1 / 240)
    pos, q, wv = np.zeros((3, n)), np.zeros((4, n)), np.zeros((6, n))
    for i, b in enumerate(bodies):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        pos[:, i] = [20.0 * i, 0.0, 500.0] + rng.normal(size=3)
        wv[3:6, i] = rng.normal(0, 3, 3)
        wv[0:3, i] = rng.normal(0, 3, 3) * (1e-5 if i < 2 else 7.0 if i == 2 else 1.0)
        p.resetBasePositionAndOrientation(b, pos[:, i].tolist(), quat.tolist(), physicsClientId=cid)
        p.resetBaseVelocity(b, wv[3:6, i].tolist(), wv[0:3, i].tolist(), physicsClientId=cid)
        q[:, i] = [-quat[0], -quat[1], -quat[2], quat[3]]  # what the reset stores as m_baseQuat
    m = None
    try:
        for _ in range(600):
            load = np.zeros((6, n))
            load[3:6] = rng.normal(0, 10, (3, n))
            load[5] += 1.5 * 9.81  # about hovering: the bodies stay far from the ground
            load[0:3, 2:] = rng.normal(0, 0.1, (3, n - 2))
            for i, b in enumerate(bodies):
                at, _ = p.getBasePositionAndOrientation(b, cid)
                p.applyExternalForce(b, -1, load[3:6, i].tolist(), at, p.WORLD_FRAME, cid)
                p.applyExternalTorque(b, -1, load[0:3, i].tolist(), p.WORLD_FRAME, cid)
            p.stepSimulation(cid)
            pos, q, wv, m = ff.step(pos, q, wv, load, m)
            rot = body_to_world(m)
            for i, b in enumerate(bodies):
                at, quat = p.getBasePositionAndOrientation(b, cid)
                lin, ang = p.getBaseVelocity(b, cid)
                assert np.array_equal(at, pos[:, i]) and np.array_equal(lin, wv[3:6, i])
                assert np.array_equal(ang, wv[0:3, i])
                # PyBullet reports the orientation after a round trip through a matrix
                assert np.abs(np.array(p.getMatrixFromQuaternion(quat)) - rot[i].ravel()).max() < 2e-15
        speeds = np.sqrt((wv[0:3] ** 2).sum(axis=0))
        assert speeds[:2].max() < 0.001 < speeds[3:].min() and speeds[2] > 10, "both branches were taken"
    finally:
        p.disconnect(cid)


def test_matrices_are_pybullets() -> None:
    rng = np.random.default_rng(3)
    q = rng.normal(size=(4, 50))
    q /= np.linalg.norm(q, axis=0)
    m = matrices(q)
    for i in range(50):
        assert np.array_equal(m[:, i], np.array(p.getMatrixFromQuaternion(q[:, i].tolist())))
        conj = [-q[0, i], -q[1, i], -q[2, i], q[3, i]]
        assert np.array_equal(body_to_world(m)[i].ravel(), np.array(p.getMatrixFromQuaternion(conj)))


def test_a_fleet_in_free_flight_flies_what_pybullet_flies() -> None:
    """The fleet's flights (take-off, legs, a velocity leg, landings and disarm), vehicles
    switching from PyBullet to the numpy step above 1 m and back below 0.75 m, against the same
    fleet stepped by PyBullet throughout: equal to 1e-12 (measured: 3e-14 in velocity, 2e-15 m in
    position; not bit for bit, because a vehicle leaving PyBullet starts from the orientation
    PyBullet reports, which can differ from Bullet's own quaternion in the last bit)."""
    got, switched = {}, {}
    for free in (False, True):
        fleet = QuadrotorFleet(3, free_flight=free, free_flight_min=1)  # any vehicle in the air flies free
        seen = []
        step = fleet.step

        def stepping(dt: float, fleet=fleet, seen=seen, step=step) -> None:
            step(dt)
            seen.append(fleet.free.copy())

        got[free] = _fly({0: fleet.members[0], 1: fleet.members[1]}, stepping)
        switched[free] = np.array(seen)
        fleet.close()
    assert not switched[False].any()
    s = switched[True][:, :2]
    assert s.any(axis=0).all() and not s[-1].any(), "both flew free, and came back to PyBullet to land"
    assert not switched[True][:, 2].any(), "the idle vehicle stays in PyBullet"
    for i in (0, 1):
        assert np.ptp(got[False][i][:, 2]) > 1.5 and got[False][i][-1, 9] == 0.0, "flies up, lands, disarms"
        assert np.abs(got[True][i] - got[False][i]).max() < 1e-12


def test_vehicles_fly_free_only_when_enough_are_in_the_air() -> None:
    """The numpy step costs about the same for 1 or 16 vehicles: below `free_flight_min`
    vehicles in the air every vehicle stays in PyBullet; from it on, those in the air fly free,
    and when too few remain (2 of hysteresis) they all go back."""
    fleet = QuadrotorFleet(6, free_flight_min=4)
    try:
        def fly(k: int) -> None:
            for i, m in enumerate(fleet.members):
                if i < k and not m.state.armed:
                    assert m.arm()
                    m.set_position_target(np.array([0.0, 0.0, -3.0]))
            for _ in range(100):
                fleet.step(0.02)

        fly(3)
        assert not fleet.free.any(), "3 of 6 in the air: PyBullet steps them all"
        fly(4)
        assert fleet.free.tolist() == [True] * 4 + [False] * 2
        for i in (0, 1, 2):
            fleet.members[i].land()
        for _ in range(300):
            fleet.step(0.02)
        assert not fleet.free.any(), "1 left in the air (fewer than 4 - 2): back to PyBullet"
        assert fleet.states[0].landed and not fleet.states[0].armed
        assert all(b is not None for b in fleet.bodies), "every vehicle has its body again"
    finally:
        fleet.close()
    small = QuadrotorFleet(4)  # the numpy step would cost more than PyBullet for 4 vehicles
    try:
        for m in small.members:
            m.arm()
            m.set_position_target(np.array([0.0, 0.0, -3.0]))
        for _ in range(100):
            small.step(0.02)
        assert not small.free.any() and (small.positions_ned[:, 2] < -2.0).all()
    finally:
        small.close()
