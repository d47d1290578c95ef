"""Rotation helpers: quaternions, matrices, Euler angles, SO(3) exp/log and slerp.

Conventions (SPEC section 1):

* Quaternions are scalar first, ``quat_wxyz = (w, x, y, z)``. Pinocchio stores the free-flyer
  and spherical-joint quaternions as (x, y, z, w); convert at that boundary with
  :func:`wxyz_to_xyzw` / :func:`xyzw_to_wxyz`.
* ``R_a_b`` maps coordinates in frame b to frame a; an IMU orientation is ``R_world_sensor``.
* Xsens Euler angles are Roll, Pitch, Yaw with ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
* Intrinsic Tait-Bryan sequences are written as axis strings: ``"YXZ"`` means
  ``R = Ry(a0) @ Rx(a1) @ Rz(a2)``.

Every function accepts a single item or a stack (leading batch dimensions) and returns the same
leading shape. Angles are radians unless the name says degrees.

This module owns the SO(3) maths of the package (NumPy side). Its CasADi twin,
:mod:`ikfusion.rotations_casadi`, writes the same formulas with the same epsilon policy for the
compiled IK step; the tests check the two equal, also near the identity and near pi.

Epsilon policy (one for every map here and in the twin):

* Below :data:`SMALL_ANGLE` the maps use their truncated Taylor series in the angle
  (``sin t / t``, ``(1 - cos t) / t^2``, ``t / sin t``, the ``Jl^-1`` coefficient); the dropped
  terms are of order ``t^4 < 1e-16`` relative.
* Above :data:`LARGE_ANGLE` the logarithm takes the rotation axis from the quaternion (the
  stable one of its four algebraic forms) instead of the skew part of ``R``, which vanishes at a
  half turn; the log is then right up to pi (at ``pi - 1e-8`` its norm is ``pi - 1e-8``).
* ``Jl^-1`` uses the half-angle form ``cot(t/2)``, finite up to and at pi.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}

#: [rad] Below this angle the SO(3) maps use truncated Taylor series (see the module notes).
SMALL_ANGLE = 1e-4
#: [rad] Above this angle the SO(3) logarithm takes its axis from the quaternion.
LARGE_ANGLE = 3.0

_EYE3 = np.eye(3)  # exp_so3's identity (read-only: every sum makes a new array)
_EYE3.setflags(write=False)
# skew's picks from (x, y, z, -x, -y, -z, 0): the rows (0, -z, y), (z, 0, -x), (-y, x, 0)
_SKEW_PICK = np.array([6, 5, 1, 2, 6, 3, 4, 0, 6])
_SKEW_PICK.setflags(write=False)
#: ``R_enu_ned``: coordinates in NED (x North, y East, z Down) to ENU (x East, y North, z Up).
R_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: ``R_enu_nwu``: coordinates in NWU (x North, y West, z Up) to ENU.
R_ENU_NWU = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def axis_rotation(axis: str, angle: npt.ArrayLike) -> np.ndarray:
    """Rotation matrix about a principal axis.

    Args:
        axis: ``"x"``, ``"y"`` or ``"z"`` (case-insensitive).
        angle: Angle(s) [rad], any shape ``S``.

    Returns:
        Matrices of shape ``S + (3, 3)``.
    """
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    i = _AXIS_INDEX[axis.lower()]
    j, k = (i + 1) % 3, (i + 2) % 3
    R = np.zeros(a.shape + (3, 3))
    R[..., i, i] = 1.0
    R[..., j, j] = c
    R[..., k, k] = c
    R[..., j, k] = -s
    R[..., k, j] = s
    return R


def euler_to_matrix(sequence: str, angles: npt.ArrayLike) -> np.ndarray:
    """Intrinsic Tait-Bryan angles to a rotation matrix.

    Args:
        sequence: Three distinct axes, e.g. ``"YXZ"`` for ``R = Ry(a0) @ Rx(a1) @ Rz(a2)``.
        angles: Shape ``S + (3,)`` [rad], in the order of ``sequence``.

    Returns:
        Matrices of shape ``S + (3, 3)``.
    """
    _check_sequence(sequence)
    a = np.asarray(angles, dtype=float)
    R = axis_rotation(sequence[0], a[..., 0])
    R = R @ axis_rotation(sequence[1], a[..., 1])
    return R @ axis_rotation(sequence[2], a[..., 2])


def matrix_to_euler(sequence: str, R: npt.ArrayLike) -> np.ndarray:
    """Rotation matrix to intrinsic Tait-Bryan angles, the inverse of :func:`euler_to_matrix`.

    The middle angle lies in [-pi/2, pi/2], the outer two in (-pi, pi]. The decomposition is
    unique while the middle angle stays away from +-pi/2 (gimbal lock).

    Args:
        sequence: Three distinct axes, e.g. ``"YXZ"``.
        R: Matrices of shape ``S + (3, 3)``.

    Returns:
        Angles of shape ``S + (3,)`` [rad].
    """
    _check_sequence(sequence)
    M = np.asarray(R, dtype=float)
    i, j, k = (_AXIS_INDEX[c] for c in sequence.lower())
    parity = 1.0 if (j - i) % 3 == 1 else -1.0
    middle = np.arcsin(np.clip(parity * M[..., i, k], -1.0, 1.0))
    first = np.arctan2(-parity * M[..., j, k], M[..., k, k])
    last = np.arctan2(-parity * M[..., i, j], M[..., i, i])
    return np.stack([first, middle, last], axis=-1)


def xsens_euler_to_matrix(
    roll_deg: npt.ArrayLike, pitch_deg: npt.ArrayLike, yaw_deg: npt.ArrayLike
) -> np.ndarray:
    """Xsens Roll/Pitch/Yaw [deg] to ``R_world_sensor = Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    angles = np.stack(np.broadcast_arrays(yaw_deg, pitch_deg, roll_deg), axis=-1)
    return euler_to_matrix("ZYX", np.deg2rad(np.asarray(angles, dtype=float)))


def matrix_to_xsens_euler(R: npt.ArrayLike) -> np.ndarray:
    """``R_world_sensor`` to Xsens ``(roll, pitch, yaw)`` [deg], shape ``S + (3,)``."""
    yaw_pitch_roll = np.rad2deg(matrix_to_euler("ZYX", R))
    return yaw_pitch_roll[..., ::-1]


def quat_wxyz_to_matrix(quat_wxyz: npt.ArrayLike) -> np.ndarray:
    """Unit quaternion(s) (w, x, y, z) to rotation matrices; the input is normalised first.

    Args:
        quat_wxyz: Shape ``S + (4,)``. NaN quaternions give NaN matrices.

    Returns:
        Shape ``S + (3, 3)``.
    """
    q = np.asarray(quat_wxyz, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def matrix_to_quat_wxyz(R: npt.ArrayLike) -> np.ndarray:
    """Rotation matrices to unit quaternions (w, x, y, z) with ``w >= 0``.

    All four algebraic candidates are formed and, per matrix, the numerically stable one (the
    largest of w, x, y, z) is kept. Small batches go through Pinocchio's quaternion constructor
    (a C++ call per matrix is cheaper than NumPy's per-operation overhead there).

    Args:
        R: Shape ``S + (3, 3)``.

    Returns:
        Shape ``S + (4,)``.
    """
    M = np.asarray(R, dtype=float)
    if _few(M):
        return _quat_wxyz_one_by_one(M)
    return _quat_wxyz_at_once(M)


def matrices_to_quats_wxyz(batches: list[np.ndarray]) -> list[np.ndarray]:
    """``[matrix_to_quat_wxyz(R) for R in batches]``, the same to the bit, in fewer passes.

    The batches that :func:`matrix_to_quat_wxyz` converts with NumPy's formulas (every
    element on its own) are converted together, in one pass.

    Args:
        batches: Rotation matrices, each of shape ``S_i + (3, 3)``.

    Returns:
        Quaternions (w, x, y, z), each of shape ``S_i + (4,)``.
    """
    arrays = [np.asarray(R, dtype=float) for R in batches]
    out: list[np.ndarray | None] = [_quat_wxyz_one_by_one(M) if _few(M) else None
                                    for M in arrays]
    rest = [k for k, q in enumerate(out) if q is None]
    if rest:
        joint = _quat_wxyz_at_once(np.concatenate([arrays[k].reshape(-1, 3, 3) for k in rest]))
        ends = np.cumsum([arrays[k].size // 9 for k in rest])
        for k, q in zip(rest, np.split(joint, ends[:-1])):
            out[k] = q.reshape(arrays[k].shape[:-2] + (4,))
    return [q for q in out if q is not None]


#: Most matrices (N, 3, 3), all finite, that :func:`matrix_to_quat_wxyz` converts one by one.
FEW_MATRICES = 24


def _few(M: np.ndarray) -> bool:
    """Whether :func:`matrix_to_quat_wxyz` converts ``M`` one matrix at a time."""
    return M.ndim == 2 or (M.ndim == 3 and len(M) <= FEW_MATRICES
                           and bool(np.isfinite(M).all()))


def _quat_wxyz_one_by_one(M: np.ndarray) -> np.ndarray:
    """:func:`matrix_to_quat_wxyz` by Pinocchio's constructor, one matrix at a time."""
    flat = M.reshape(-1, 3, 3)
    q = np.array([pin.Quaternion(m).coeffs() for m in flat])  # (x, y, z, w)
    q = q[:, [3, 0, 1, 2]] / np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0.0] *= -1.0
    return q.reshape(M.shape[:-2] + (4,))


def _quat_wxyz_at_once(M: np.ndarray) -> np.ndarray:
    """:func:`matrix_to_quat_wxyz` by NumPy's formulas over all matrices at once."""
    m00, m01, m02 = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
    m10, m11, m12 = M[..., 1, 0], M[..., 1, 1], M[..., 1, 2]
    m20, m21, m22 = M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
    # 4 * q_i * q_j products; candidate k is the one whose k-th component is largest.
    a, b, c = m21 - m12, m02 - m20, m10 - m01
    d, e, f = m01 + m10, m02 + m20, m12 + m21
    diag = np.stack([1.0 + m00 + m11 + m22, 1.0 + m00 - m11 - m22, 1.0 - m00 + m11 - m22,
                     1.0 - m00 - m11 + m22], axis=-1)
    branch = np.argmax(diag, axis=-1)
    t0, t1, t2, t3 = (diag[..., k] for k in range(4))
    w = np.choose(branch, [t0, a, b, c])
    x = np.choose(branch, [a, t1, d, e])
    y = np.choose(branch, [b, d, t2, f])
    z = np.choose(branch, [c, e, f, t3])
    q = np.stack([w, x, y, z], axis=-1) / np.sqrt(w * w + x * x + y * y + z * z)[..., None]
    return np.where(q[..., :1] < 0.0, -q, q)


def continuous_quaternions(quat: npt.ArrayLike) -> np.ndarray:
    """A sequence of quaternions (N, 4) (either component order) with continuous signs.

    ``q`` and ``-q`` are one rotation; each quaternion is flipped, where needed, into the
    hemisphere of the last finite one before it, so that averaging or interpolating along the
    sequence is meaningful. Rows with NaN stay NaN.
    """
    q = np.array(quat, dtype=float)
    idx = np.flatnonzero(np.isfinite(q).all(axis=1))
    if len(idx) > 1:
        dots = np.einsum("ij,ij->i", q[idx[1:]], q[idx[:-1]])
        signs = np.concatenate([[1.0], np.cumprod(np.where(dots < 0.0, -1.0, 1.0))])
        q[idx] *= signs[:, None]
    return q


def wxyz_to_xyzw(quat_wxyz: npt.ArrayLike) -> np.ndarray:
    """Reorder (w, x, y, z) to Pinocchio's (x, y, z, w)."""
    q = np.asarray(quat_wxyz, dtype=float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def xyzw_to_wxyz(quat_xyzw: npt.ArrayLike) -> np.ndarray:
    """Reorder Pinocchio's (x, y, z, w) to (w, x, y, z)."""
    q = np.asarray(quat_xyzw, dtype=float)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


def skew(v: npt.ArrayLike) -> np.ndarray:
    """Skew-symmetric matrices ``[v]x`` with ``[v]x @ u = v x u``; shape ``S + (3, 3)``."""
    a = np.asarray(v, dtype=float)
    if a.shape == (3,):  # one vector: a literal is several times faster (the EKF's case)
        x, y, z = a.tolist()
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    # (x, y, z, -x, -y, -z, 0) per vector, picked into the rows (one take)
    signed = np.concatenate((a, -a, np.zeros(a.shape[:-1] + (1,))), axis=-1)
    return signed.take(_SKEW_PICK, axis=-1).reshape(a.shape[:-1] + (3, 3))


def exp_so3(rotvec: npt.ArrayLike) -> np.ndarray:
    """Exponential map: rotation vector(s) ``omega`` [rad] to ``R = exp([omega]x)`` (Rodrigues).

    Args:
        rotvec: Shape ``S + (3,)`` [rad].

    Returns:
        Rotation matrices of shape ``S + (3, 3)``.
    """
    w = np.asarray(rotvec, dtype=float)
    # np.linalg.norm(w, axis=-1)'s own sum of squares and root, without its argument handling
    theta = np.sqrt(np.add.reduce(w * w, axis=-1))[..., None, None]
    K = skew(w)
    small = theta < SMALL_ANGLE
    if not small.any():  # the same numbers as below, without the series' branch
        return _EYE3 + np.sin(theta) / theta * K + (1.0 - np.cos(theta)) / theta**2 * (K @ K)
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return _EYE3 + a * K + b * (K @ K)


def rotvec_to_quat_wxyz(rotvec: npt.ArrayLike) -> np.ndarray:
    """Unit quaternion(s) (w, x, y, z) of rotation vector(s) [rad], shape ``S + (4,)``.

    ``(cos(t/2), sin(t/2) / t * rotvec)`` with ``t = |rotvec|``, the factor's series
    ``1/2 - t^2/48`` below :data:`SMALL_ANGLE`. One vector (3,) is computed with scalar maths
    (the same formula, several times faster: the EKF calls it per IMU sample).
    """
    w = np.asarray(rotvec, dtype=float)
    if w.shape == (3,):
        x, y, z = w.tolist()
        t = math.sqrt(x * x + y * y + z * z)
        k = 0.5 - t * t / 48.0 if t < SMALL_ANGLE else math.sin(0.5 * t) / t
        return np.array([math.cos(0.5 * t), k * x, k * y, k * z])
    theta = np.linalg.norm(w, axis=-1, keepdims=True)
    small = theta < SMALL_ANGLE
    safe = np.where(small, 1.0, theta)
    scale = np.where(small, 0.5 - theta**2 / 48.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([np.cos(0.5 * theta), scale * w], axis=-1)


def log_so3(R: npt.ArrayLike) -> np.ndarray:
    """Logarithm map: rotation matrices to rotation vectors [rad] with norm in [0, pi].

    The angle is ``atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2)``; the vector is the skew part of
    ``R`` scaled by ``angle / sin(angle)`` (its series below :data:`SMALL_ANGLE`), or, above
    :data:`LARGE_ANGLE`, the quaternion's vector part scaled to the angle (the skew part vanishes
    at a half turn). At exactly pi either of the two opposite vectors may be returned.

    Args:
        R: Rotation matrices, shape ``S + (3, 3)``.

    Returns:
        Rotation vectors of shape ``S + (3,)``.
    """
    M = np.asarray(R, dtype=float)
    if M.shape == (3, 3):
        return _log_so3_single(M)
    vee = 0.5 * np.stack([M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0],
                          M[..., 1, 0] - M[..., 0, 1]], axis=-1)
    cos = np.clip(0.5 * (M[..., 0, 0] + M[..., 1, 1] + M[..., 2, 2] - 1.0), -1.0, 1.0)
    sin = np.linalg.norm(vee, axis=-1)
    theta = np.arctan2(sin, cos)
    small = theta < SMALL_ANGLE
    scale = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small, 1.0, sin))
    out = vee * scale[..., None]
    near_pi = theta > LARGE_ANGLE
    if np.any(near_pi):
        q = matrix_to_quat_wxyz(M[near_pi])
        v = q[..., 1:]
        n = np.linalg.norm(v, axis=-1, keepdims=True)
        out[near_pi] = v * (2.0 * np.arctan2(n, q[..., :1]) / n)
    return out


def _log_so3_single(M: np.ndarray) -> np.ndarray:
    """:func:`log_so3` of one matrix (3, 3) with scalar maths: the same formula and branches."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = M.tolist()
    x, y, z = 0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01)
    cos = min(1.0, max(-1.0, 0.5 * (m00 + m11 + m22 - 1.0)))
    sin = math.sqrt(x * x + y * y + z * z)
    theta = math.atan2(sin, cos)
    if theta > LARGE_ANGLE:
        q = matrix_to_quat_wxyz(M)
        n = math.sqrt(float(q[1:] @ q[1:]))
        return q[1:] * (2.0 * math.atan2(n, float(q[0])) / n)
    if math.isnan(theta):
        return np.full(3, np.nan)
    scale = 1.0 + theta * theta / 6.0 if theta < SMALL_ANGLE else theta / sin
    return np.array([scale * x, scale * y, scale * z])


def left_jacobian_inverse(e: npt.ArrayLike) -> np.ndarray:
    """Inverse left Jacobian ``Jl^-1(e)`` of SO(3) at rotation vector(s) ``e`` [rad].

    Linearises the logarithm under a left perturbation: ``log(exp(w) exp(e)) ~ e + Jl^-1(e) w``.
    ``Jl^-1(e) = I - [e]x / 2 + (1/t^2 - cot(t/2) / (2 t)) [e]x^2`` with ``t = |e|``; the
    coefficient is its series ``1/12 + t^2/720`` below :data:`SMALL_ANGLE`.

    Args:
        e: Shape ``S + (3,)`` [rad], norms up to pi.

    Returns:
        Shape ``S + (3, 3)``.
    """
    v = np.asarray(e, dtype=float)
    theta = np.linalg.norm(v, axis=-1)[..., None, None]
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    coeff = np.where(small, 1.0 / 12.0 + theta**2 / 720.0,
                     1.0 / t**2 - np.cos(0.5 * t) / (2.0 * t * np.sin(0.5 * t)))
    K = skew(v)
    return np.eye(3) - 0.5 * K + coeff * (K @ K)


def right_jacobian_inverse(e: npt.ArrayLike) -> np.ndarray:
    """Inverse right Jacobian ``Jr^-1(e) = Jl^-1(-e)``: ``log(exp(e) exp(w)) ~ e + Jr^-1(e) w``.

    Args:
        e: Shape ``S + (3,)`` [rad].

    Returns:
        Shape ``S + (3, 3)``.
    """
    return left_jacobian_inverse(-np.asarray(e, dtype=float))


def angle_between(R_a: npt.ArrayLike, R_b: npt.ArrayLike) -> np.ndarray:
    """Geodesic angle [rad] between rotations, ``|log(R_a^T R_b)|``; shape ``S``."""
    A = np.asarray(R_a, dtype=float)
    B = np.asarray(R_b, dtype=float)
    return np.linalg.norm(log_so3(np.swapaxes(A, -1, -2) @ B), axis=-1)


def slerp(quat0_wxyz: npt.ArrayLike, quat1_wxyz: npt.ArrayLike, t: npt.ArrayLike) -> np.ndarray:
    """Spherical linear interpolation between unit quaternions (w, x, y, z) along the short arc.

    Args:
        quat0_wxyz: Start, shape ``S + (4,)``.
        quat1_wxyz: End, same shape.
        t: Fraction in [0, 1], broadcast against ``S``.

    Returns:
        Unit quaternions of shape ``broadcast(S, t.shape) + (4,)``.
    """
    q0 = np.asarray(quat0_wxyz, dtype=float)
    q1 = np.asarray(quat1_wxyz, dtype=float)
    tt = np.asarray(t, dtype=float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-9
    safe = np.where(near, 1.0, sin_theta)
    w0 = np.where(near, 1.0 - tt, np.sin((1.0 - tt) * theta) / safe)
    w1 = np.where(near, tt, np.sin(tt * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def random_rotations(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rotation matrices drawn uniformly on SO(3) (normalised Gaussian quaternions)."""
    q = rng.normal(size=(n, 4))
    return quat_wxyz_to_matrix(q)


def _check_sequence(sequence: str) -> None:
    s = sequence.lower()
    if len(s) != 3 or set(s) != {"x", "y", "z"}:
        raise ValueError(f"Euler sequence must be three distinct axes of xyz, got {sequence!r}")
