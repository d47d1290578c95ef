"""Posture prior: each ball joint prefers a reference rotation (the N-pose by default).

With a small weight it only decides what the sensors leave open: how a rotation between two
sensed segments is spread over the joints between them (equal squared rotation vectors spread
it evenly over the spine between Pelvis and T8, or the neck between T8 and Head), and where
unsensed segments (toes, a limb without sensors) rest.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from ...rotations import log_so3, quat_wxyz_to_matrix, right_jacobian_inverse, xyzw_to_wxyz
from ..configuration import Configuration
from ..fast_math import any_true
from .base import Task


class PostureTask(Task):
    """Residual ``e_j = log(R_ref_j^T @ R_parent_child_j)`` [rad] for each ball joint j.

    Args:
        idx_q: Start of each joint's quaternion (x, y, z, w) in ``q``.
        idx_v: Start of each joint's rotation vector in the tangent space.
        weights: Weight of each joint [1/rad^2].
        R_reference: Reference joint rotations (j, 3, 3); identity when omitted.
        axis_weights: Relative weight of each rotation-vector component in the child frame
            (j, 3); ones when omitted. A knee that should stay a hinge weighs its x (abduction)
            and z (rotation) components more than y (flexion).
    """

    def __init__(self, idx_q: Sequence[int], idx_v: Sequence[int], weights: npt.ArrayLike,
                 R_reference: npt.ArrayLike | None = None,
                 axis_weights: npt.ArrayLike | None = None) -> None:
        self.idx_q = np.asarray(idx_q, dtype=int)
        self.idx_v = np.asarray(idx_v, dtype=int)
        self.weights = np.asarray(weights, dtype=float).reshape(-1)
        n = len(self.idx_q)
        # replaced, never edited: read-only (a compiled step keeps it in its slot while so)
        self.R_reference = (np.repeat(np.eye(3)[None], n, axis=0) if R_reference is None
                            else np.asarray(R_reference, dtype=float).reshape(n, 3, 3))
        self.R_reference.setflags(write=False)
        self.axis_weights = (np.ones((n, 3)) if axis_weights is None
                             else np.asarray(axis_weights, dtype=float).reshape(n, 3))
        self._q_cols = self.idx_q[:, None] + np.arange(4)
        self._v_cols = self.idx_v[:, None] + np.arange(3)

    @classmethod
    def from_joints(cls, joints: Mapping[str, object], weights: Mapping[str, float],
                    default_weight: float,
                    axis_weights: Mapping[str, Sequence[float]] | None = None) -> PostureTask:
        """Build from ``HumanModel.ball_joints`` and per-joint weights (others: default)."""
        names = list(joints)
        axes = axis_weights or {}
        return cls([joints[n].idx_q for n in names],  # type: ignore[attr-defined]
                   [joints[n].idx_v for n in names],  # type: ignore[attr-defined]
                   [weights.get(n, default_weight) for n in names],
                   axis_weights=[axes.get(n, (1.0, 1.0, 1.0)) for n in names])

    def row_weights(self) -> np.ndarray:
        """Per-row weights (3 rows per joint)."""
        return (self.weights[:, None] * self.axis_weights).reshape(-1)

    def _joint_rotations(self, q: np.ndarray) -> np.ndarray:
        return quat_wxyz_to_matrix(xyzw_to_wxyz(q[self._q_cols]))

    def compute_error(self, configuration: Configuration) -> np.ndarray:
        """Stacked joint rotation vectors relative to the reference (3j,) [rad]."""
        R = self._joint_rotations(configuration.q)
        return log_so3(np.swapaxes(self.R_reference, 1, 2) @ R).reshape(-1)

    def compute_jacobian(self, configuration: Configuration) -> np.ndarray:
        """Block-sparse Jacobian (3j, nv): ``Jr^-1(e_j)`` on each joint's tangent columns."""
        e = self.compute_error(configuration).reshape(-1, 3)
        J = np.zeros((e.size, configuration.model.nv))
        blocks = right_jacobian_inverse(e)
        for k, cols in enumerate(self._v_cols):
            J[3 * k:3 * k + 3, cols] = blocks[k]
        return J

    def add_objective(self, configuration: Configuration, H: np.ndarray, c: np.ndarray) -> None:
        """Block-diagonal assembly (no dense Jacobian)."""
        e = self.compute_error(configuration).reshape(-1, 3)
        self.add_blocks(e, right_jacobian_inverse(e), H, c)

    def add_blocks(self, e: np.ndarray, B: np.ndarray, H: np.ndarray, c: np.ndarray) -> None:
        """Accumulate the objective from errors (j, 3) and Jacobian blocks ``Jr^-1`` (j, 3, 3)."""
        w = self.weights
        active = w > 0
        if not any_true(active):
            return
        e, B, cols = e[active], B[active], self._v_cols[active]
        W = w[active, None] * self.axis_weights[active]  # (k, 3) diagonal weights
        BtB = np.swapaxes(B, 1, 2) @ (W[:, :, None] * B)
        Bte = np.einsum("kji,kj->ki", B, W * e)
        H[cols[:, :, None], cols[:, None, :]] += BtB
        c[cols] += Bte
