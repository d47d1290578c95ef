"""Forward kinematics of a whole motion at once: frame placements for N configurations.

Writing a result folder needs every segment's and site's pose at every frame. Calling
Pinocchio's ``framesForwardKinematics`` once per frame costs tens of microseconds of Python per
frame and frame id; here each joint is composed for all N configurations in one NumPy operation,
following Pinocchio's own order (``oMi = oMparent * jointPlacement * joint(q)``,
``oMf = oMi * frame.placement``; quaternions as Eigen turns them into matrices), so the results
equal Pinocchio's to rounding (about 1e-15).

Free-flyer, spherical and revolute joints about x, y or z are composed here; a model with any
other joint type falls back to Pinocchio frame by frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from .placements_kernel import kernel_placements


def quat_xyzw_matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) stored (x, y, z, w), as Eigen does it.

    The quaternions are used as given (not normalised), like Pinocchio's joints.
    """
    x, y, z, w = (quat_xyzw[:, i] for i in range(4))
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    R = np.empty((len(quat_xyzw), 3, 3))
    R[:, 0, 0] = 1.0 - (tyy + tzz)
    R[:, 0, 1] = txy - twz
    R[:, 0, 2] = txz + twy
    R[:, 1, 0] = txy + twz
    R[:, 1, 1] = 1.0 - (txx + tzz)
    R[:, 1, 2] = tyz - twx
    R[:, 2, 0] = txz - twy
    R[:, 2, 1] = tyz + twx
    R[:, 2, 2] = 1.0 - (txx + tyy)
    return R


def _axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) by ``angle`` (N,) [rad] about the coordinate axis ``axis``."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.zeros((len(angle), 3, 3))
    R[:, axis, axis] = 1.0
    R[:, i, i] = c
    R[:, j, j] = c
    R[:, i, j] = -s
    R[:, j, i] = s
    return R


def _rot_rot(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A @ B`` for stacks of 3x3 matrices, each sum taken in Eigen's order (no BLAS)."""
    A, B = np.asarray(A), np.asarray(B)
    return (A[..., :, 0, None] * B[..., None, 0, :] + A[..., :, 1, None] * B[..., None, 1, :]
            + A[..., :, 2, None] * B[..., None, 2, :])


def _rot_vec(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``A @ v`` for stacks of 3x3 matrices and 3-vectors, summed in Eigen's order."""
    A, v = np.asarray(A), np.asarray(v)
    return A[..., :, 0] * v[..., 0, None] + A[..., :, 1] * v[..., 1, None] \
        + A[..., :, 2] * v[..., 2, None]


#: Pinocchio joint types composed here, and the revolute ones' axis.
_REVOLUTE = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}
_SUPPORTED = {"JointModelFreeFlyer", "JointModelSpherical", *_REVOLUTE}


def _joint_rotation(joint: pin.JointModel, q: np.ndarray) -> np.ndarray:
    """The joint's own rotation (N, 3, 3) along ``q``."""
    kind, i = joint.shortname(), joint.idx_q
    if kind == "JointModelFreeFlyer":
        return quat_xyzw_matrix(q[:, i + 3:i + 7])
    if kind == "JointModelSpherical":
        return quat_xyzw_matrix(q[:, i:i + 4])
    return _axis_rotation(_REVOLUTE[kind], q[:, i])


def _joint_translation(joint: pin.JointModel, q: np.ndarray) -> np.ndarray | None:
    """The joint's own translation (N, 3) along ``q``, None for a rotation only."""
    i = joint.idx_q
    return q[:, i:i + 3] if joint.shortname() == "JointModelFreeFlyer" else None


@dataclass
class JointRotations:
    """The joints' world rotations of one model along one motion, kept between queries.

    A motion moved about by its root's translation only (levelled, locked, lifted: every
    coordinate but ``q[:, :3]`` unchanged) has the same rotations in every query:
    :func:`frame_placements` given this computes each joint's once and the positions anew, with
    the very values it computes without it. Rotations kept for other coordinates are dropped
    (compared exactly), so a query of another motion is never wrong, only not faster.

    Attributes:
        model: The model they belong to.
        coordinates: ``q[:, 3:]`` of the motion they belong to.
        R_world_joint: Joint index -> (N, 3, 3).
    """

    model: pin.Model | None = None
    coordinates: np.ndarray | None = None
    R_world_joint: dict[int, np.ndarray] = field(default_factory=dict)

    def of(self, model: pin.Model, Q: np.ndarray) -> dict[int, np.ndarray]:
        """The rotations kept for ``model`` along ``Q`` (emptied when they are another's)."""
        if self.model is not model or self.coordinates is None \
                or not np.array_equal(self.coordinates, Q[:, 3:]):
            self.model, self.coordinates = model, Q[:, 3:].copy()
            self.R_world_joint = {}
        return self.R_world_joint


def frame_placements(model: pin.Model, q: np.ndarray, frame_ids: Sequence[int],
                     rotations: JointRotations | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World positions (N, F, 3) [m] and rotations ``R_world_frame`` (N, F, 3, 3) of frames.

    Args:
        model: The Pinocchio model.
        q: Configurations (N, nq) (Pinocchio's layout: quaternions stored x, y, z, w).
        frame_ids: The frames wanted, in order.
        rotations: The joints' rotations kept from an earlier query of this motion (updated
            here); the results are the same with or without.
    """
    Q = np.asarray(q, dtype=float).reshape(-1, model.nq)
    n, ids = len(Q), list(frame_ids)
    p_out = np.empty((n, len(ids), 3))
    R_out = np.empty((n, len(ids), 3, 3))
    if any(model.joints[j].shortname() not in _SUPPORTED for j in range(1, model.njoints)):
        data = pin.Data(model)  # (createData() builds the same, several times slower)
        for k, qk in enumerate(Q):
            pin.framesForwardKinematics(model, data, qk)
            for i, f in enumerate(ids):
                p_out[k, i], R_out[k, i] = data.oMf[f].translation, data.oMf[f].rotation
        return p_out, R_out
    needed = {model.frames[f].parentJoint for f in ids}
    for j in sorted(needed):  # every ancestor too
        while j > 0:
            j = model.parents[j]
            needed.add(j)
    if rotations is None:  # the C kernel when built: the same numbers
        done = kernel_placements(model, Q, ids, sorted(needed - {0}), _is_identity)
        if done is not None:
            return done
    kept = {} if rotations is None else rotations.of(model, Q)
    R_joint: dict[int, np.ndarray] = {0: np.broadcast_to(np.eye(3), (n, 3, 3))}
    p_joint: dict[int, np.ndarray] = {0: np.zeros((n, 3))}
    for j in sorted(needed - {0}):  # Pinocchio numbers a parent before its children
        placement = model.jointPlacements[j]
        joint = model.joints[j]
        p_motion = _joint_translation(joint, Q)
        turned = not _is_identity(placement.rotation)
        parent = model.parents[j]
        if j in kept:
            R_joint[j] = kept[j]
        else:
            R_motion = _joint_rotation(joint, Q)
            # liMi = jointPlacement * joint(q)
            R_local = _rot_rot(placement.rotation, R_motion) if turned else R_motion
            # the world frame: oMi = liMi; else oMi = oMparent * liMi
            R_joint[j] = kept[j] = R_local if parent == 0 else \
                _rot_rot(R_joint[parent], R_local)
        p_local = np.broadcast_to(placement.translation, (n, 3)) if p_motion is None else \
            placement.translation + (_rot_vec(placement.rotation, p_motion) if turned
                                     else p_motion)
        if parent == 0:
            p_joint[j] = np.array(p_local)
            continue
        p_joint[j] = p_joint[parent] + _rot_vec(R_joint[parent], p_local)
    for i, f in enumerate(ids):
        frame = model.frames[f]
        R_i, p_i = R_joint[frame.parentJoint], p_joint[frame.parentJoint]
        rotation = frame.placement.rotation
        R_out[:, i] = R_i if _is_identity(rotation) else _rot_rot(R_i, rotation)
        p_out[:, i] = p_i + _rot_vec(R_i, frame.placement.translation)
    return p_out, R_out


def _is_identity(R: np.ndarray) -> bool:
    """Whether a placement's rotation is exactly the identity (its product is then skipped).

    Multiplying by an exact identity changes no value (only the sign of an exact zero), and
    every joint and site placement of the human model is one: half of the products of a
    motion's kinematics.
    """
    return bool(R[0, 0] == 1.0 and R[1, 1] == 1.0 and R[2, 2] == 1.0
                and not R[0, 1] and not R[0, 2] and not R[1, 0] and not R[1, 2]
                and not R[2, 0] and not R[2, 1])
