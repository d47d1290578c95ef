"""Segment orientations put onto the human model directly: configurations without a solver.

Every ball joint of the model is the rotation between its two segments, so a mapped BVH frame
(all 23 segment orientations and the pelvis origin) fixes a configuration in closed form:
``R_parent_child = R_world_parent^T R_world_child``, decomposed into the joint's anatomical
angles and held inside its range of motion. Joints are taken parents first and each one turns
from the orientation its parent actually reached, so a segment past a limit stops there and its
children still take their own orientations. What a limited segment misses is split with its
parent segment when that one moves only it (limbs: a thigh and a shank, a forearm and a hand):
the parent turns by half, the least-squares split of two equally weighted orientation errors,
as the per-frame solver spreads it. Inside the ranges this is the exact pose the solver
converges to (up to its step tolerance).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping

import numpy as np

from ..model.ball_joints import BallJoint
from ..model.human_model import HumanModel
from ..rotations import exp_so3, log_so3, matrices_to_quats_wxyz, matrix_to_quat_wxyz, wxyz_to_xyzw

#: A joint angle past its range by more than this counts as held by the range [rad] (the
#: whole-body solver's own step tolerance: closer than this, the two poses agree).
LIMIT_TOLERANCE_RAD = 1e-3


def configurations_from_orientations(model: HumanModel,
                                     R_world_segment: Mapping[str, np.ndarray],
                                     p_world_pelvis: np.ndarray
                                     ) -> tuple[np.ndarray, np.ndarray]:
    """Configurations (N, nq) whose segments take the given orientations, within joint ranges.

    Args:
        model: A human model with ball joints (every segment and joint of SPEC section 2).
        R_world_segment: Segment name -> (N, 3, 3) world orientation (MVN segment convention,
            world Z up); every segment of the model.
        p_world_pelvis: (N, 3) pelvis origin [m].

    Returns:
        Configurations (N, nq) in Pinocchio's layout (quaternions x, y, z, w), and (N,) whether
        a joint range held a segment away from its orientation by more than
        :data:`LIMIT_TOLERANCE_RAD` in that frame.
    """
    p_pelvis = np.asarray(p_world_pelvis, dtype=float).reshape(-1, 3)
    n = len(p_pelvis)
    pin_model = model.model
    frames = {s: pin_model.frames[model.segment_frame_id(s)] for s in model.segment_names}
    root = frames["Pelvis"]
    q = np.tile(model.neutral(), (n, 1))
    # the pelvis frame sits on the free-flyer joint: R_world_root = R_world_pelvis F^T
    R_root = R_world_segment["Pelvis"] @ root.placement.rotation.T
    q[:, :3] = p_pelvis - R_root @ root.placement.translation
    limited = np.zeros(n, dtype=bool)
    reached = {"Pelvis": np.asarray(R_world_segment["Pelvis"], dtype=float)}
    by_child = {j.spec.child: j for j in model.ball_joints.values()}
    children = Counter(j.spec.parent for j in model.ball_joints.values())
    # R_parent_child of every joint in all frames, converted to quaternions together at the
    # end; the frames placed again afterwards overwrite theirs, in the order they were placed
    placed: list[tuple[BallJoint, np.ndarray]] = []
    replaced: list[tuple[BallJoint, np.ndarray, np.ndarray]] = []

    def place(joint: BallJoint, target: np.ndarray, rows: np.ndarray | slice) -> np.ndarray:
        """Turn ``joint`` toward the child orientation ``target`` in ``rows``, within range."""
        spec = joint.spec
        F_parent = frames[spec.parent].placement.rotation
        F_child = frames[spec.child].placement.rotation
        placement = pin_model.jointPlacements[joint.joint_id].rotation
        # R_world_child = R_world_parent F_parent^T placement R_joint F_child
        R_before = reached[spec.parent][rows] @ (F_parent.T @ placement)
        R_joint = np.swapaxes(R_before, 1, 2) @ target @ F_child.T
        angles = spec.angles_from_rotation(R_joint)
        lower = np.radians([a.lower_deg for a in spec.angles])
        upper = np.radians([a.upper_deg for a in spec.angles])
        outside = np.any((angles < lower - LIMIT_TOLERANCE_RAD)
                         | (angles > upper + LIMIT_TOLERANCE_RAD), axis=1)
        if outside.any():
            R_joint[outside] = spec.rotation(np.clip(angles[outside], lower, upper))
        if spec.child not in reached:
            reached[spec.child] = np.empty((n, 3, 3))
        reached[spec.child][rows] = R_before @ R_joint @ F_child
        if isinstance(rows, slice):
            placed.append((joint, R_joint))
        else:
            replaced.append((joint, rows, matrix_to_quat_wxyz(R_joint)))
        return outside

    for joint in model.ball_joints.values():  # parents before children
        spec = joint.spec
        target = np.asarray(R_world_segment[spec.child], dtype=float)
        outside = place(joint, target, slice(None))
        limited |= outside
        above = by_child.get(spec.parent)
        if not outside.any() or above is None or children[spec.parent] != 1:
            continue
        # Held by the range: the parent takes half of what the child misses (equal weights:
        # the least-squares split of the two orientation errors), then the child again.
        rows = np.flatnonzero(outside)
        missed = log_so3(target[rows] @ np.swapaxes(reached[spec.child][rows], 1, 2))
        place(above, exp_so3(0.5 * missed) @ reached[spec.parent][rows], rows)
        place(joint, target[rows], rows)
    root_quat, *quats = matrices_to_quats_wxyz([R_root, *(R for _, R in placed)])
    q[:, 3:7] = wxyz_to_xyzw(root_quat)
    for (joint, _), quat in zip(placed, quats, strict=True):
        q[:, joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(quat)
    for joint, rows, quat in replaced:
        q[rows, joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(quat)
    return q, limited
