"""Bullet's step of a free-flying body, in numpy over many bodies at once (issue 13).

A fleet's vehicles in the air touch nothing: PyBullet's `stepSimulation` then does, for each
single-body `btMultiBody` (createMultiBody makes Featherstone bodies, not btRigidBody), what
`free_step` does here, in the same floating-point operations in the same order, so that a
step gives the same bits (tests/sim/vehicle/test_free_flight.py compares them step by step on
random states and over whole flights):

1. forces: the applied force plus `gravity * mass` (btMultiBodyDynamicsWorld::solveExternalForces);
   the applied torque (a force applied at the centre of mass adds `0 x F`, which is zero);
2. `btMultiBody::computeAccelerationsArticulatedBodyAlgorithmMultiDof` for a base without links,
   in the body frame (`M` = btMatrix3x3(m_baseQuat), world to body): with `w = M omega`,
   `v = M vel`, the zero-acceleration force is `-(M tau) + w x (I w)` (gyroscopic term on, the
   default) and `-(M F) + m (w x v)`; `solveImatrix` divides by I and m; the accelerations
   back in the world are `M^T (-(...)/I)` and `M^T (-(...)/m + w x v)`. Damping is zero here
   (changeDynamics linearDamping=0, angularDamping=0): its terms add zeros. (A btVector3 divided
   by a scalar is multiplied by its reciprocal; by a vector, divided.)
3. `applyDeltaVeeMultiDof`: velocities += acceleration * dt, each clamped to +-100
   (m_maxCoordinateVelocity);
4. `stepPositionsMultiDof`: position += dt * velocity, and the quaternion by Bullet's
   exponential map (Taylor expansion below 0.001 rad/s, the angle limited to pi/4 a step),
   then normalised.

`q` is Bullet's own m_baseQuat, the rotation world to body: the conjugate of the orientation
PyBullet reports (PyBullet reports it after a round trip through a matrix, which can differ
from the conjugate in the last bit; resetBasePositionAndOrientation(pos, conj(q)) stores q
exactly). Arrays are component first: positions and velocities (3, N), quaternions (4, N).
No contact, no sleeping (PyBullet's bodies cannot sleep unless asked), no joint: a body near
the ground must be stepped by PyBullet (QuadrotorFleet switches below 0.75 m).
"""

from __future__ import annotations

import numpy as np

#: btMultiBody::m_maxCoordinateVelocity
MAX_COORDINATE_VELOCITY = 100.0
#: ANGULAR_MOTION_THRESHOLD (btTransformUtil.h): 0.5 * SIMD_HALF_PI, SIMD_HALF_PI = SIMD_2_PI * 0.25
ANGULAR_MOTION_THRESHOLD = 0.5 * (6.283185307179586232 * 0.25)


def _gathers() -> dict[str, np.ndarray]:
    """Row indices for np.take, so each product below is one multiplication of two contiguous
    (rows, N) arrays (numpy's per-call cost, not its arithmetic, is most of a step of tens of
    bodies; broadcasting and strided views cost several times a plain call)."""
    g = {}
    # M (9, N) row-major times 4 stacked vectors (12, N), block j of 12 rows: M[i, j] * s[3 k + j]
    # for the result row 3 k + i; M^T times 2 stacked vectors (6, N): M[j, i] * a[3 k + j]
    g["m_fwd"] = np.array([3 * i + j for j in range(3) for k in range(4) for i in range(3)])
    g["s_fwd"] = np.array([3 * k + j for j in range(3) for k in range(4) for i in range(3)])
    g["m_back"] = np.array([3 * j + i for j in range(3) for k in range(2) for i in range(3)])
    g["a_back"] = np.array([3 * k + j for j in range(3) for k in range(2) for i in range(3)])
    # cross products w x v and w x (I w) from rows (w 0-2, v 3-5, I w 6-8): a_y b_z - a_z b_y, ...
    g["cross_l"] = np.array([1, 2, 0, 1, 2, 0, 2, 0, 1, 2, 0, 1])
    g["cross_r"] = np.array([5, 3, 4, 8, 6, 7, 4, 5, 3, 7, 8, 6])
    # quaternion product q * (x2, c), rows (x1 y1 z1 w1 0-3, x2 y2 z2 4-6, c 7, -x2 -y2 -z2 8-10):
    # x = ((w1 x2 + x1 c) + y1 z2) - z1 y2, ..., w = ((w1 c + x1 (-x2)) + y1 (-y2)) - z1 z2
    g["quat_l"] = np.array([3, 3, 3, 3, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2])
    g["quat_r"] = np.array([4, 5, 6, 7, 7, 7, 7, 8, 6, 4, 5, 9, 5, 6, 4, 6])
    # setRotation from the products p (9, N) = (v_i * v_j s) and ws = (w x s, w y s, w z s):
    # diagonal 1 - (yy + zz), 1 - (xx + zz), 1 - (xx + yy); off-diagonal xy -+ wz, xz +- wy, yz -+ wx
    g["diag_a"], g["diag_b"] = np.array([4, 0, 0]), np.array([8, 8, 4])
    g["off_p"], g["off_w"] = np.array([1, 2, 5]), np.array([2, 1, 0])
    # entries of (diagonal 0-2, plus 3-5, minus 6-8) in row-major order
    g["entries"] = np.array([0, 6, 4, 3, 1, 8, 7, 5, 2])
    return g


_G = _gathers()
# numpy scalars as 0-d arrays: an operation with a Python float converts it every call (~0.2 us
# of a ~0.35 us operation on tens of bodies); the values, and so the results, are the same
_ONE, _TWO = np.array(1.0), np.array(2.0)


def matrices(q: np.ndarray) -> np.ndarray:
    """(9, N) row-major btMatrix3x3::setRotation of (4, N) quaternions (x, y, z, w), Bullet's
    arithmetic: s = 2 / |q|^2, xs = x s, ..., xy - wz, 1 - (yy + zz), .... The matrix of the
    conjugate quaternion is exactly the transpose (the products do not change, the w terms
    change sign), so `matrices(q).T.reshape(N, 3, 3).transpose(0, 2, 1)` is the body-to-world
    rotation PyBullet's getMatrixFromQuaternion makes of conj(q)."""
    g = _G
    sq = q * q
    vs = q[:3] * (_TWO / (((sq[0] + sq[1]) + sq[2]) + sq[3]))
    p = (q[:3, None] * vs[None]).reshape(9, -1)  # p[3 i + j] = v_i * (v_j s): xx xy xz . yy yz . . zz
    ws = (q[3] * vs).take(g["off_w"], axis=0)  # wz, wy, wx
    off = p.take(g["off_p"], axis=0)  # xy, xz, yz
    stack = np.concatenate((_ONE - (p.take(g["diag_a"], axis=0) + p.take(g["diag_b"], axis=0)), off + ws, off - ws))
    return stack.take(g["entries"], axis=0)


def body_to_world(m: np.ndarray) -> np.ndarray:
    """(N, 3, 3) body-to-world rotations from matrices(q) (9, N) (world to body): M^T per body."""
    return m.T.reshape(-1, 3, 3).transpose(0, 2, 1)


class FreeFlight:
    """Bullet's free-body step for bodies of one mass and one inertia, N at once. Written for few
    numpy calls on contiguous arrays (each call costs more than its arithmetic on tens of
    bodies), every element by the same IEEE operations as Bullet's C++ (no fused multiply-add
    there or here)."""

    def __init__(self, mass: float, inertia: tuple[float, float, float], gravity: tuple[float, float, float],
                 dt: float) -> None:
        """inertia: the local inertia diagonal Bullet holds (p.getDynamicsInfo(body, -1)[2]);
        gravity: as given to setGravity."""
        self.m, self.dt = float(mass), float(dt)
        self.inertia = tuple(float(x) for x in inertia)
        # btVector3 * btScalar, as solveExternalForces adds it to the applied force
        self.weight = tuple(float(g) * self.m for g in gravity)
        self._taylor = (self.dt * self.dt * self.dt) * 0.020833333333
        self._n = -1
        # 0-d arrays of the scalars (see _ONE): dt, m, 1/m, the velocity clamp, 0.5, 0.001
        self._dt, self._m, self._inv_m = np.array(self.dt), np.array(self.m), np.array(1.0 / self.m)
        self._vmax, self._vmin, self._half, self._milli = (np.array(MAX_COORDINATE_VELOCITY),
                                                           np.array(-MAX_COORDINATE_VELOCITY), np.array(0.5),
                                                           np.array(0.001))
        # the angle limit can only bind if the clamped angular velocity, |w| <= 100 sqrt(3), turns
        # more than pi/4 in a step (dt > 4.5 ms): never at 240 Hz
        self._can_limit = MAX_COORDINATE_VELOCITY * 3 ** 0.5 * self.dt > ANGULAR_MOTION_THRESHOLD

    def _consts(self, n: int) -> None:
        """Constant arrays of the fleet's size (a broadcast costs more than a plain operation)."""
        self._n = n
        self._i3 = np.repeat(np.array(self.inertia)[:, None], n, axis=1)
        self._w3 = np.repeat(np.array(self.weight)[:, None], n, axis=1)
        self._plain_weight = self.weight[0] == 0.0 and self.weight[1] == 0.0  # F + (0, 0, w): z alone
        self._wz = np.array(self.weight[2])

    def step(self, pos: np.ndarray, q: np.ndarray, wv: np.ndarray, load: np.ndarray,
             m: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One step of every body. pos (3, N); q (4, N) Bullet's m_baseQuat; wv (6, N) the
        angular then linear velocities (world); load (6, N) the torque then force applied this
        step (world, at the centre of mass, gravity excluded); m: matrices(q), if made already.
        Returns the new (pos, q, wv, matrices(new q)), fresh arrays."""
        g, dt, n = _G, self._dt, q.shape[1]
        if n != self._n:
            self._consts(n)
        if m is None:
            m = matrices(q)
        s = np.concatenate((wv, load))  # omega, vel, torque, force
        if self._plain_weight:  # x + 0.0 == x
            s[11] += self._wz
        else:
            s[9:12] += self._w3
        prod = m.take(g["m_fwd"], axis=0) * s.take(g["s_fwd"], axis=0)
        local = (prod[0:12] + prod[12:24]) + prod[24:36]  # body frame: w, v, M tau, M F
        wvi = np.concatenate((local[0:6], local[0:3] * self._i3))  # w, v, I w
        prod = wvi.take(g["cross_l"], axis=0) * wvi.take(g["cross_r"], axis=0)
        cr = prod[0:6] - prod[6:12]  # w x v, w x (I w)
        # zero-acceleration force: (-(M tau) + w x I w, -(M F) + m (w x v)); accelerations
        # -(z / I) == (M tau - w x I w) / I and -(z * (1/m)) == (M F - m (w x v)) * (1/m)
        # (btVector3 / btVector3 divides, btVector3 / btScalar multiplies by the reciprocal)
        acc = np.empty((6, n))
        np.subtract(local[6:9], cr[3:6], out=acc[0:3])
        np.divide(acc[0:3], self._i3, out=acc[0:3])
        np.subtract(local[9:12], cr[0:3] * self._m, out=acc[3:6])
        np.multiply(acc[3:6], self._inv_m, out=acc[3:6])
        np.add(acc[3:6], cr[0:3], out=acc[3:6])  # + w x v: the base's linear acceleration in world terms
        prod = m.take(g["m_back"], axis=0) * acc.take(g["a_back"], axis=0)
        wv1 = wv + ((prod[0:6] + prod[6:12]) + prod[12:18]) * dt
        np.minimum(np.maximum(wv1, self._vmin, out=wv1), self._vmax, out=wv1)
        omega1 = wv1[0:3]
        pos1 = pos + dt * wv1[3:6]
        # exponential map of the world angular velocity, Bullet's pQuatUpdateFun for the base
        sq = omega1 * omega1
        angle = np.sqrt((sq[0] + sq[1]) + sq[2])
        if self._can_limit and angle.max() * dt > ANGULAR_MOTION_THRESHOLD:
            angle = np.where(angle * dt > ANGULAR_MOTION_THRESHOLD, ANGULAR_MOTION_THRESHOLD / dt, angle)
        if angle.min() >= 0.001:
            scale = np.sin(self._half * angle * dt) / angle
        else:
            small = angle < self._milli
            scale = 0.5 * self.dt - self._taylor * angle * angle
            if not small.all():
                big = ~small
                a = angle[big]
                scale[big] = np.sin(0.5 * a * self.dt) / a
        x2 = omega1 * -scale  # the update quaternion is (-axis, cos(angle dt / 2)), axis = omega * scale
        qx = np.concatenate((q, x2, np.cos(angle * dt * self._half)[None], -x2))
        prod = qx.take(g["quat_l"], axis=0) * qx.take(g["quat_r"], axis=0)
        q1 = ((prod[0:4] + prod[4:8]) + prod[8:12]) - prod[12:16]
        sq = q1 * q1
        q1 *= _ONE / np.sqrt(((sq[0] + sq[1]) + sq[2]) + sq[3])  # btQuaternion::normalize: *= 1 / length
        return pos1, q1, wv1, matrices(q1)
