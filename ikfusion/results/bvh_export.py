"""The solved motion of a :class:`HumanModel` as a BVH file (MVN joint names, metres).

Each BVH joint is a model segment at its proximal joint, with the N-pose offsets of the model;
its channels are the segment's rotation relative to its parent (the root: ``R_world_pelvis``
and the pelvis position). Animation tools open it as they open MVN's own BVH export.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.bvh import BvhSkeleton, write_bvh
from ..model.human_model import HumanModel
from ..rotations import quat_wxyz_to_matrix, xyzw_to_wxyz

#: End sites written after leaf segments: segment -> site that marks its tip.
_END_SITES = {"Head": "HeadTop", "LeftToe": "LeftToe", "RightToe": "RightToe"}


def model_skeleton(model: HumanModel) -> BvhSkeleton:
    """The model's segments as a BVH joint tree (N-pose offsets [m], Z-up, facing +X)."""
    names = model.segment_names
    index = {n: i for i, n in enumerate(names)}
    parents = np.full(len(names), -1, dtype=int)
    q0 = model.neutral()
    data = model.forward(q0)
    origins = np.array([data.oMf[model.segment_frame_id(n)].translation for n in names])
    for joint in model.ball_joints.values():
        parents[index[joint.spec.child]] = index[joint.spec.parent]
    offsets = origins.copy()
    for i, p in enumerate(parents):
        if p >= 0:
            offsets[i] = origins[i] - origins[p]
    end_parents, end_offsets = [], []
    for segment, site in _END_SITES.items():
        if segment in index and site in model.site_names:
            end_parents.append(index[segment])
            end_offsets.append(data.oMf[model.site_frame_id(site)].translation - origins[
                index[segment]])
    for side in ("Left", "Right"):
        hand = f"{side}Hand"
        if hand in index and model.body is not None:
            end_parents.append(index[hand])
            end_offsets.append(np.array([0.0, 0.0, -model.body.dimension("hand")]))
    return BvhSkeleton(tuple(names), parents, offsets, np.array(end_parents, dtype=int),
                       np.array(end_offsets).reshape(-1, 3))


def local_rotations(model: HumanModel, q: np.ndarray) -> np.ndarray:
    """``R_parent_segment`` per frame and segment (F, 23, 3, 3); root: ``R_world_pelvis``."""
    Q = np.atleast_2d(q)
    names = model.segment_names
    index = {n: i for i, n in enumerate(names)}
    children = {index[joint.spec.child] for joint in model.ball_joints.values()}
    # one joint at a time (arrays that stay in the cache: faster than all joints at once)
    out = np.empty((len(Q), len(names), 3, 3))
    for i in set(range(1, len(names))) - children:  # none in the human model
        out[:, i] = np.eye(3)
    out[:, 0] = quat_wxyz_to_matrix(xyzw_to_wxyz(Q[:, 3:7]))
    for joint in model.ball_joints.values():
        out[:, index[joint.spec.child]] = quat_wxyz_to_matrix(
            xyzw_to_wxyz(Q[:, joint.idx_q:joint.idx_q + 4]))
    return out


def write_motion_bvh(path: str | Path, model: HumanModel, q: np.ndarray, frame_time: float,
                     up: str = "z", rotations: np.ndarray | None = None) -> Path:
    """Write the configurations ``q`` (F, nq) as a BVH file.

    Args:
        path: Output file (written atomically).
        model: The human model (ball joints).
        q: Configurations.
        frame_time: [s].
        up: ``"z"`` (our world) or ``"y"`` (the usual BVH convention of animation tools).
        rotations: :func:`local_rotations` of ``q`` when already computed (the same file).
    """
    if up not in ("z", "y"):
        raise ValueError(f"up must be 'z' or 'y', not {up!r}")
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    if Q.shape[1] != model.model.nq or not np.isfinite(Q).all():
        raise ValueError("q must be finite configurations of the model")
    R_local = local_rotations(model, Q) if rotations is None else rotations
    return write_bvh(path, model_skeleton(model), Q[:, :3], R_local,
                     frame_time, up=up)  # type: ignore[arg-type]
