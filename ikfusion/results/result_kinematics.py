"""What the writers of a result folder need from a solved motion, computed once for all.

``joint_angles.csv`` and ``motion.mot`` both need the joint angles, ``segments.csv``,
``sites.csv`` and ``motion.mot`` the segments' world poses, the joint angles and
``motion.bvh`` each segment's rotation relative to its parent: computing them once, for every
frame at once, spares the second computation (the values are the very same ones).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..ik.pose import Motion
from ..model.motion_kinematics import frame_placements
from ..rotations import matrix_to_quat_wxyz
from .bvh_export import local_rotations
from .quats_kernel import kernel_quats_wxyz

#: Frames whose segment quaternions are computed per pass: the temporaries of a block stay in
#: the processor's cache (about a third faster than one pass over the whole motion).
QUAT_BLOCK_FRAMES = 256


@dataclass(frozen=True)
class ResultKinematics:
    """A motion's joint angles and segment and site placements, every frame.

    Attributes:
        angles: (N, C) joint angles [deg], columns ``model.angle_columns``.
        p_world_segment: (N, S, 3) segment origins [m], segments ``model.segment_names``.
        R_world_segment: (N, S, 3, 3) segment orientations.
        p_world_site: (N, M, 3) site positions [m], sites ``model.site_names``.
        R_parent_segment: (N, S, 3, 3) segment rotations relative to their parent segment
            (the pelvis: ``R_world_pelvis``), :func:`.bvh_export.local_rotations`.
        segment_index: Segment name -> index into the S axis.
    """

    angles: np.ndarray
    p_world_segment: np.ndarray
    R_world_segment: np.ndarray
    p_world_site: np.ndarray
    R_parent_segment: np.ndarray
    segment_index: dict[str, int]

    @classmethod
    def of(cls, motion: Motion) -> ResultKinematics:
        """Compute them (world frame: X forward, Y left, Z up)."""
        model = motion.model
        segments = [model.segment_frame_id(n) for n in model.segment_names]
        sites = [model.site_frame_id(n) for n in model.site_names]
        p, R = frame_placements(model.model, motion.q, segments + sites)
        S = len(segments)
        index = {n: i for i, n in enumerate(model.segment_names)}
        local = local_rotations(model, motion.q)
        # motion.joint_angles() from the same rotations (its own computation of them)
        angles = model.joint_angle_matrix(motion.q, rotations={
            name: local[:, index[joint.spec.child]] for name, joint in model.ball_joints.items()})
        return cls(angles, p[:, :S], R[:, :S], p[:, S:], local, index)

    def segment_quats_wxyz(self) -> np.ndarray:
        """(N, S, 4) segment orientations as unit quaternions (w, x, y, z) with ``w >= 0``.

        :func:`ikfusion.rotations.matrix_to_quat_wxyz` of ``R_world_segment``, block by block
        of frames (each matrix is converted on its own: the same values).
        """
        R = self.R_world_segment
        done = kernel_quats_wxyz(R) if R.ndim == 4 and R.size else None
        if done is not None:  # the C kernel: the same numbers
            return done
        if not len(R):
            return matrix_to_quat_wxyz(R)
        return np.concatenate([matrix_to_quat_wxyz(R[s:s + QUAT_BLOCK_FRAMES])
                               for s in range(0, len(R), QUAT_BLOCK_FRAMES)])

    def segment_poses(self, names: set[str]) -> tuple[dict[str, np.ndarray],
                                                       dict[str, np.ndarray]]:
        """``R_world_segment`` (N, 3, 3) and ``p_world_segment`` (N, 3) [m] of ``names``."""
        index = self.segment_index
        return ({n: self.R_world_segment[:, index[n]] for n in names},
                {n: self.p_world_segment[:, index[n]] for n in names})
