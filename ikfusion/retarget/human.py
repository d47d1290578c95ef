"""Retargeting onto the human model at another body size (actor-to-character retargeting).

The target is :class:`~ikfusion.model.HumanModel` built for ``height``: every segment of the
source is an orientation task (same segment convention, so no rest-pose offsets), the pelvis
follows the source's pelvis path scaled by the ratio of hip heights, and the source's contact
phases are contact hints, so planted feet are held by the solver's no-slip constraints.
"""

from __future__ import annotations

import numpy as np

from ..ik.frame import Frame
from ..ik.pose import Motion
from ..ik.solver import Solver
from ..model.body import Body
from ..model.human_model import HumanModel
from ..rotations import matrix_to_quat_wxyz, wxyz_to_xyzw
from .source import HumanMotion

#: Weight of the scaled pelvis path [1/m^2] (orientations weigh 1/rad^2 each).
ROOT_WEIGHT = 10.0


def hip_height(model: HumanModel) -> float:
    """Height of the hip joints above the floor in the model's N-pose [m]."""
    q = model.neutral()
    return float(np.mean([model.segment_position(q, s)[2]
                          for s in ("RightUpperLeg", "LeftUpperLeg")]))


def configuration_from_segments(model: HumanModel, source: HumanMotion, k: int,
                                scale: float = 1.0) -> np.ndarray:
    """A configuration of ``model`` from the source's frame ``k``.

    Its joints are the source's relative segment rotations and its pelvis is the source's,
    scaled by ``scale``.
    """
    index = {s: i for i, s in enumerate(source.segments)}
    R = source.R_world_segment[k]
    q = model.neutral().copy()
    if "Pelvis" in index:
        q[:3] = scale * source.p_world_segment[k, index["Pelvis"]]
        q[3:7] = wxyz_to_xyzw(matrix_to_quat_wxyz(R[index["Pelvis"]]))
    for joint in model.ball_joints.values():
        a, b = index.get(joint.spec.parent), index.get(joint.spec.child)
        if a is not None and b is not None:
            q[joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(matrix_to_quat_wxyz(R[a].T @ R[b]))
    return q


def source_joint_angles(model: HumanModel, source: HumanMotion) -> np.ndarray:
    """The source's anatomical joint angles (N, 3 * joints) [deg] in ``model.angle_columns``."""
    return model.joint_angle_matrix(np.array([configuration_from_segments(model, source, k)
                                              for k in range(len(source))]))


def retarget_human(source: HumanMotion, height: float, progress: bool = False) -> Motion:
    """The source's motion on the human model of body ``height`` [m].

    Returns:
        The solved motion of the target model.
    """
    model = HumanModel.from_body(Body.from_height(height))
    scale = hip_height(model) / source.hip_height
    index = {s: i for i, s in enumerate(source.segments)}
    segments = [s for s in model.segment_names if s in index]
    pelvis = index.get("Pelvis")
    frames = []
    for k, t in enumerate(source.time):
        hints = {n: bool(c) for n, c in zip(source.contact_names, source.contacts[k])}
        root = None if pelvis is None else scale * source.p_world_segment[k, pelvis]
        frames.append(Frame(float(t), {s: source.R_world_segment[k, index[s]] for s in segments},
                            contacts=hints, root_position=root, root_position_weight=ROOT_WEIGHT))
    # hard limits: a retargeted motion stays inside the target's ranges
    return Solver(model, joint_range_overshoot_deg=0.0).solve(frames, progress=progress,
                                                              total=len(frames))
