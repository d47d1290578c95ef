""":func:`ikfusion.model.motion_kinematics.frame_placements` by a small C kernel.

The NumPy path composes each joint for all configurations in some forty array operations per
joint; the C kernel (``motion_kinematics.c``) composes each configuration's joints and frames
in one pass, with the same floating-point operations in the same order: the same numbers.
Free-flyer and spherical joints only (the human model's); any other joint, or no kernel (no
compiler, ``IKFUSION_NO_COMPILE``), leaves the work to NumPy.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from ..native.kernel import c_function, kernel_source

#: What is used when the kernel cannot be compiled (the end of the build warning).
FALLBACK = "NumPy computes the segment and site poses of the result files instead"
#: Joint types the kernel composes: 1 for a free flyer, 0 for a spherical joint.
_KINDS = {"JointModelFreeFlyer": 1, "JointModelSpherical": 0}

_P, _N = ctypes.c_void_p, ctypes.c_int64


class _Placements(ctypes.Structure):
    """``struct placements`` of ``motion_kinematics.c``."""

    _fields_ = [("q", _P), ("n", _N), ("nq", _N), ("joints", _N), ("plan", _P),
                ("placement", _P), ("frames", _N), ("frame_plan", _P),
                ("frame_placement", _P), ("work", _P), ("p_out", _P), ("R_out", _P)]


def _rigid(placement: pin.SE3) -> list[float]:
    """A placement as the kernel reads it: R row-major (9) then t (3) [m]."""
    return [*np.asarray(placement.rotation, dtype=float).ravel().tolist(),
            *np.asarray(placement.translation, dtype=float).tolist()]


def kernel_placements(model: pin.Model, Q: np.ndarray, ids: list[int], joints: Sequence[int],
                      is_identity: Callable[[np.ndarray], bool]
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """World positions (N, F, 3) [m] and rotations (N, F, 3, 3) of frames ``ids``, or None.

    Args:
        model: The Pinocchio model.
        Q: (N, nq) configurations.
        ids: The frames wanted, in order.
        joints: The joints they need, ancestors included, parents first (no universe).
        is_identity: The test of an exact identity rotation (whose product is skipped).

    Returns:
        None without the kernel or with a joint it does not compose.
    """
    if any(model.joints[j].shortname() not in _KINDS for j in joints):
        return None
    function = c_function(kernel_source(__name__, "motion_kinematics.c"), "frame_placements",
                          FALLBACK)
    if function is None:
        return None
    slot = {0: 0, **{j: s + 1 for s, j in enumerate(joints)}}
    plan, placement = [], []
    for j in joints:
        rotated = not is_identity(model.jointPlacements[j].rotation)
        plan.append([_KINDS[model.joints[j].shortname()], model.joints[j].idx_q,
                     slot[model.parents[j]], int(rotated)])
        placement.append(_rigid(model.jointPlacements[j]))
    frame_plan, frame_placement = [], []
    for f in ids:
        frame = model.frames[f]
        rotated = not is_identity(frame.placement.rotation)
        frame_plan.append([slot[frame.parentJoint], int(rotated)])
        frame_placement.append(_rigid(frame.placement))
    Q = np.ascontiguousarray(Q, dtype=float)
    arrays = [np.array(plan, dtype=np.int64).reshape(-1, 4),
              np.array(placement, dtype=float).reshape(-1, 12),
              np.array(frame_plan, dtype=np.int64).reshape(-1, 2),
              np.array(frame_placement, dtype=float).reshape(-1, 12),
              np.empty((len(joints) + 1, 12))]
    n = len(Q)
    p_out, R_out = np.empty((n, len(ids), 3)), np.empty((n, len(ids), 3, 3))
    function(ctypes.byref(_Placements(
        Q.ctypes.data, n, Q.shape[1], len(joints), arrays[0].ctypes.data,
        arrays[1].ctypes.data, len(ids), arrays[2].ctypes.data, arrays[3].ctypes.data,
        arrays[4].ctypes.data, p_out.ctypes.data, R_out.ctypes.data)))
    return p_out, R_out
