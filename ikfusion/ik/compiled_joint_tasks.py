"""The joint-space tasks of the compiled step (CasADi): the columns' bends and the persistence.

Twins of the NumPy tasks, summed into the step function's objective (:mod:`.compiled`) so a
step needs no NumPy work for them:

* the column pairs of :class:`.tasks.EvenChainTask` (weights ``w_chain``, each pair's
  difference of rotation vectors wanted at zero) and of :class:`.tasks.ChainShareTask`
  (weights ``w_share``, the difference wanted where the configuration ``q_previous`` has it):
  ``e = log(R_i) - log(R_j)``, ``J = [Jr^-1(log R_i), -Jr^-1(log R_j)]`` on the two joints'
  columns, both tasks sharing ``J``: ``H += J^T (W_chain + W_share) J`` and
  ``c += J^T (W_chain e + W_share (e - d))`` with ``d`` the difference at ``q_previous``;
* the persistence task (:class:`.sensed_pose.Persistence`, a :class:`.tasks.DampingTask`):
  ``H += diag(w_persist)`` and ``c += w_persist (q ⊖ q_persist)``, the difference taken per
  joint as Pinocchio's ``difference`` (``log(R_persist^T R)`` for a spherical joint, of the
  quaternions, the change of angle for a revolute one); the free-flyer's columns are not covered
  (:func:`joint_columns`): their weights must be zero here.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache

import casadi as ca
import numpy as np
import pinocchio as pin

from ..model.ball_joints import BallJoint
from ..rotations import SMALL_ANGLE
from ..rotations_casadi import log_so3, quat_xyzw_to_matrix, right_jacobian_inverse

_REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")




def quaternion_log(quat: ca.SX) -> ca.SX:
    """Rotation vector (3,) [rad] of a unit quaternion (x, y, z, w), its angle in [0, pi].

    The rotation's shorter way, as Pinocchio's ``difference`` of spherical joints and
    :func:`ikfusion.rotations.log_so3` of its matrix (to rounding), for a fraction of the
    operations: ``2 atan2(|v|, |w|) / |v|`` times ``v`` (signed as ``w``), its series
    ``2 / |w| (1 - x^2 / 3)``, ``x = |v| / |w|``, below ``x = SMALL_ANGLE``.
    """
    v, w = quat[0:3], quat[3]
    sign = ca.if_else(w < 0.0, -1.0, 1.0)
    n, w_abs = ca.norm_2(v), sign * w
    small = n < SMALL_ANGLE * w_abs
    x = n / ca.if_else(small, w_abs, 1.0)
    scale = ca.if_else(small, 2.0 * (1.0 - x * x / 3.0) / ca.if_else(small, w_abs, 1.0),
                       2.0 * ca.atan2(n, w_abs) / ca.if_else(small, 1.0, n))
    return sign * scale * v


def _quaternion_between(first: ca.SX, second: ca.SX) -> ca.SX:
    """The quaternion (x, y, z, w) of ``R_first^T R_second`` of unit quaternions (x, y, z, w)."""
    a, aw = -first[0:3], first[3]  # the conjugate of the first
    b, bw = second[0:3], second[3]
    return ca.vertcat(aw * b + bw * a + ca.cross(a, b), aw * bw - ca.dot(a, b))


def chain_objective(q: ca.SX, q_previous: ca.SX, pairs: Sequence[tuple[BallJoint, BallJoint]],
                    w_chain: ca.SX, w_share: ca.SX, nv: int) -> tuple[ca.SX, ca.SX]:
    """``(H (nv, nv), c (nv))`` of the even-chain and chain-share pairs (module docstring).

    Args:
        q: Configuration (nq).
        q_previous: The configuration whose differences the share task holds (nq).
        pairs: Neighbouring joints (:attr:`.tasks.EvenChainTask.pairs`).
        w_chain: Even-chain weights, 3 per pair [1/rad^2].
        w_share: Chain-share weights, 3 per pair [1/rad^2].
        nv: Tangent size.
    """
    H, c = ca.SX(nv, nv), ca.SX(nv, 1)
    if not pairs:
        return H, c
    rows, errors, wanted = [], [], []
    logs: dict[int, list[ca.SX]] = {}  # joint -> (log, Jr^-1, log at q_previous), each once
    for first, second in pairs:
        for joint in (first, second):
            if joint.idx_q not in logs:
                iq = joint.idx_q
                logs[joint.idx_q] = _chain_logs().call([q[iq:iq + 4], q_previous[iq:iq + 4]])
        block = ca.SX(3, nv)
        ends = [logs[first.idx_q], logs[second.idx_q]]
        for (_, Jr_inv, _), joint, sign in zip(ends, (first, second), (1.0, -1.0)):
            block[:, joint.idx_v:joint.idx_v + 3] = sign * Jr_inv
        rows.append(block)
        errors.append(ends[0][0] - ends[1][0])
        wanted.append(ends[0][2] - ends[1][2])
    J, e, d = ca.vertcat(*rows), ca.vertcat(*errors), ca.vertcat(*wanted)
    WJ = ca.diag(w_chain + w_share) @ J
    return J.T @ WJ, J.T @ (w_chain * e + w_share * (e - d))


@cache
def _chain_logs() -> ca.Function:
    """``(quaternion (4), previous quaternion (4)) -> (log (3), Jr^-1 (3, 3), previous log)``.

    A ball joint's rotation vector [rad] and ``Jr^-1`` at ``q``, and its rotation vector at
    ``q_previous`` (:func:`quaternion_log`): one body in the generated code, called per joint.
    """
    quaternion, previous = ca.SX.sym("quaternion", 4), ca.SX.sym("previous", 4)
    e, theta = log_so3(quat_xyzw_to_matrix(quaternion))
    return ca.Function("ik_chain_logs", [quaternion, previous],
                       [e, right_jacobian_inverse(e, theta), quaternion_log(previous)],
                       {"never_inline": True, "cse": True})


@cache
def _persistence_error() -> ca.Function:
    """``(reference quaternion (4), quaternion (4)) -> q ⊖ q_persist (3)`` [rad] of a ball joint.

    One body in the generated code, called per joint (``never_inline``).
    """
    reference, quaternion = ca.SX.sym("reference", 4), ca.SX.sym("quaternion", 4)
    return ca.Function("ik_persistence_error", [reference, quaternion],
                       [quaternion_log(_quaternion_between(reference, quaternion))],
                       {"never_inline": True, "cse": True})


def joint_columns(model: pin.Model) -> np.ndarray:
    """(nv,) bool: the tangent columns :func:`persistence_objective` covers (all but the root)."""
    covered = np.zeros(model.nv, dtype=bool)
    for j in range(1, model.njoints):
        kind = model.joints[j].shortname()
        if kind == "JointModelSpherical" or kind in _REVOLUTE:
            covered[model.idx_vs[j]:model.idx_vs[j] + model.nvs[j]] = True
    return covered


def persistence_objective(model: pin.Model, q: ca.SX, q_persist: ca.SX, w_persist: ca.SX
                          ) -> tuple[ca.SX, ca.SX]:
    """``(diagonal of H (nv), c (nv))`` of the persistence task: ``w``, ``w (q ⊖ q_persist)``.

    Columns outside :func:`joint_columns` get nothing (their weights must be zero).
    """
    diagonal, c = ca.SX(model.nv, 1), ca.SX(model.nv, 1)
    for j in range(1, model.njoints):
        kind = model.joints[j].shortname()
        iq, iv = model.idx_qs[j], model.idx_vs[j]
        if kind == "JointModelSpherical":
            e = _persistence_error()(q_persist[iq:iq + 4], q[iq:iq + 4])
        elif kind in _REVOLUTE:
            e = q[iq] - q_persist[iq]
        else:
            continue
        n = model.nvs[j]
        diagonal[iv:iv + n] = w_persist[iv:iv + n]
        c[iv:iv + n] = w_persist[iv:iv + n] * e
    return diagonal, c
