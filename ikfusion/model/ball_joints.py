"""Turn triplets of revolute joints that share an origin into spherical (SO(3)) joints.

A URDF cannot express a ball joint, so the human URDF writes each as three revolute joints with
zero-length, massless links between them. Tracking orientations through those revolute angles
would inherit the Euler singularity; here the triplets are merged into
``pinocchio.JointModelSpherical`` joints, whose configuration is a unit quaternion and whose
tangent space is the rotation vector, so nothing is singular. The conversion is exact: the
spherical joint's rotation equals ``R(a1, q1) @ R(a2, q2) @ R(a3, q3)`` of the triplet.

A triplet (j1, j2, j3) is merged when j2 is the only child of j1 and j3 the only child of j2, the
placements of j2 and j3 are the identity, the bodies of j1 and j2 carry no mass and no other
frames, and the three axes are distinct principal axes (+-x, +-y, +-z). Everything else (a robot's
offset hip joints, for example) is kept as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..rotations import log_so3
from .joints import AngleSpec, JointSpec

_ANGLE_SUFFIXES = ("flex", "abd", "rot")


@dataclass(frozen=True)
class BallJoint:
    """A spherical joint of the converted model and the anatomical angles it reports.

    Attributes:
        name: Joint name (e.g. ``"jRightKnee"``).
        joint_id: Pinocchio joint index in the converted model.
        idx_q: Start of its quaternion (x, y, z, w) in ``q``.
        idx_v: Start of its rotation vector in the tangent space.
        spec: Euler sequence, signs and ranges of its three angles.
        revolute_ids: The three joint indices it replaces in the revolute model.
    """

    name: str
    joint_id: int
    idx_q: int
    idx_v: int
    spec: JointSpec
    revolute_ids: tuple[int, int, int]


@dataclass(frozen=True)
class ConvertedModel:
    """Result of :func:`merge_revolute_triplets`.

    Attributes:
        model: The model with spherical joints.
        ball_joints: Ball joint name -> :class:`BallJoint`, in model order.
        joint_map: Revolute-model joint index -> converted-model joint index (triplet members map
            to their ball joint).
    """

    model: pin.Model
    ball_joints: dict[str, BallJoint]
    joint_map: dict[int, int]


def revolute_axes(model: pin.Model) -> dict[int, np.ndarray]:
    """Unit rotation axis, in its own frame, of every 1-DoF revolute joint of ``model``."""
    q0 = pin.neutral(model)
    axes = {}
    for j in range(1, model.njoints):
        if model.nqs[j] != 1 or model.nvs[j] != 1:
            continue
        joint = model.joints[j]
        q = q0.copy()
        q[model.idx_qs[j]] = 1.0
        motion = joint.createData()
        joint.calc(motion, q)  # the joint's own motion at 1 rad, without the whole tree
        if np.linalg.norm(motion.M.translation) > 1e-12:
            continue  # prismatic or helical
        axis = log_so3(motion.M.rotation)
        axes[j] = axis / np.linalg.norm(axis)
    return axes


def _principal(axis: np.ndarray) -> tuple[str, int] | None:
    k = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[k]) - 1.0) > 1e-9:
        return None
    return "xyz"[k], 1 if axis[k] > 0 else -1


def _only_child(children: dict[int, list[int]], joint_id: int) -> int | None:
    """The one child joint of ``joint_id`` (None for none or several); ``children`` by parent."""
    kids = children.get(joint_id, [])
    return kids[0] if len(kids) == 1 else None


def _bare_link(model: pin.Model, carried: dict[int, list[pin.Frame]], joint_id: int) -> bool:
    """True when a joint's body has no mass and carries no frame but its own link and joint.

    ``carried`` lists each joint's frames.
    """
    if model.inertias[joint_id].mass > 0.0:
        return False
    frames = carried.get(joint_id, [])
    return all(f.type in (pin.FrameType.JOINT, pin.FrameType.BODY) for f in frames) and len(
        frames) <= 2


def _by_parent(items: list[tuple[int, object]]) -> dict[int, list]:
    """``(parent, item)`` pairs grouped by parent, each group in the given order."""
    out: dict[int, list] = {}
    for parent, item in items:
        out.setdefault(parent, []).append(item)
    return out


def _triplet_spec(model: pin.Model, frames: list[pin.Frame], ids: tuple[int, int, int],
                  axes: list[tuple[str, int]]) -> JointSpec:
    """The joint spec of a triplet; ``frames`` is ``list(model.frames)`` (read once)."""
    names = [model.names[j] for j in ids]
    stems = {n.rsplit("_", 1)[0] for n in names}
    suffixes = [n.rsplit("_", 1)[-1] for n in names]
    if len(stems) == 1 and sorted(suffixes) == sorted(_ANGLE_SUFFIXES):
        name, angle_names = stems.pop(), suffixes
    else:
        name, angle_names = "+".join(names), names
    angles = []
    for j, (axis, sign), angle in zip(ids, axes, angle_names):
        iq = model.idx_qs[j]
        lo = float(np.degrees(model.lowerPositionLimit[iq]))
        hi = float(np.degrees(model.upperPositionLimit[iq]))
        angles.append(AngleSpec(angle, axis, sign, lo, hi))
    joint_frame = next(f for f in frames
                       if f.type == pin.FrameType.JOINT and f.parentJoint == ids[0])
    parent = frames[joint_frame.parentFrame].name
    child_bodies = [f.name for f in frames
                    if f.parentJoint == ids[2] and f.type == pin.FrameType.BODY]
    child = child_bodies[0] if child_bodies else name
    return JointSpec(name, parent, child, (angles[0], angles[1], angles[2]))


def find_triplets(model: pin.Model) -> list[tuple[tuple[int, int, int], list[tuple[str, int]]]]:
    """Revolute triplets of ``model`` that form exact ball joints, with their axes and signs."""
    found = []
    all_axes = revolute_axes(model)
    parents = list(model.parents)  # Pinocchio's containers are slow to index from Python
    children = _by_parent([(parents[j], j) for j in range(1, model.njoints)])
    carried = _by_parent([(f.parentJoint, f) for f in model.frames])
    for j1 in range(1, model.njoints):
        j2 = _only_child(children, j1)
        j3 = _only_child(children, j2) if j2 is not None else None
        if j2 is None or j3 is None:
            continue
        ids = (j1, j2, j3)
        if any(j not in all_axes for j in ids):
            continue
        maybe = [_principal(all_axes[j]) for j in ids]
        principal = [p for p in maybe if p is not None]
        if len(principal) != 3 or len({p[0] for p in principal}) != 3:
            continue
        identity = all(model.jointPlacements[j].isIdentity(1e-12) for j in (j2, j3))
        if identity and _bare_link(model, carried, j1) and _bare_link(model, carried, j2):
            found.append((ids, principal))
    return found


def merge_revolute_triplets(model: pin.Model) -> ConvertedModel:
    """A copy of ``model`` in which every exact revolute triplet is one spherical joint.

    Args:
        model: A model loaded from URDF (revolute joints, optionally a free-flyer root).

    Returns:
        The converted model, its ball joints and the joint index map.
    """
    triplets = find_triplets(model)
    first_of = {ids[0]: (ids, axes) for ids, axes in triplets}
    inner = {j for ids, _ in triplets for j in ids[:2]}
    last_of = {ids[2]: ids for ids, _ in triplets}
    new = pin.Model()
    new.name = model.name
    joint_map: dict[int, int] = {0: 0}
    ball_joints: dict[str, BallJoint] = {}
    joint_frames: dict[int, int] = {}
    members = {j for ids, _ in triplets for j in ids}
    frames = list(model.frames)
    for j in range(1, model.njoints):
        if j in members and j not in first_of:
            continue
        parent = joint_map[model.parents[j]]
        if j in first_of:
            ids, axes = first_of[j]
            spec = _triplet_spec(model, frames, ids, axes)
            jid = new.addJoint(parent, pin.JointModelSpherical(), model.jointPlacements[j],
                               spec.name)
            new.inertias[jid] = model.inertias[ids[2]]
            for member in ids:
                joint_map[member] = jid
            ball_joints[spec.name] = BallJoint(spec.name, jid, new.idx_qs[jid], new.idx_vs[jid],
                                               spec, ids)
            joint_frames[jid] = new.addJointFrame(jid)
        else:
            jid = new.addJoint(parent, model.joints[j], model.jointPlacements[j], model.names[j])
            new.inertias[jid] = model.inertias[j]
            joint_map[j] = jid
            iq, nq = model.idx_qs[j], model.nqs[j]
            new.lowerPositionLimit[new.idx_qs[jid]:new.idx_qs[jid] + nq] = \
                model.lowerPositionLimit[iq:iq + nq]
            new.upperPositionLimit[new.idx_qs[jid]:new.idx_qs[jid] + nq] = \
                model.upperPositionLimit[iq:iq + nq]
            iv, nv = model.idx_vs[j], model.nvs[j]
            new.velocityLimit[new.idx_vs[jid]:new.idx_vs[jid] + nv] = \
                model.velocityLimit[iv:iv + nv]
            new.effortLimit[new.idx_vs[jid]:new.idx_vs[jid] + nv] = model.effortLimit[iv:iv + nv]
    _copy_frames(model, new, joint_map, inner, last_of, joint_frames)
    return ConvertedModel(new, ball_joints, joint_map)


def _copy_frames(model: pin.Model, new: pin.Model, joint_map: dict[int, int], inner: set[int],
                 last_of: dict[int, tuple[int, int, int]],
                 joint_frames: dict[int, int]) -> dict[int, int]:
    frame_map: dict[int, int] = {0: 0}
    for fid in range(1, model.nframes):
        frame = model.frames[fid]
        pj = frame.parentJoint
        if pj in inner:
            continue
        if pj in last_of and frame.type == pin.FrameType.JOINT:
            frame_map[fid] = joint_frames[joint_map[pj]]
            continue
        parent_frame = frame_map.get(frame.parentFrame, joint_frames.get(joint_map[pj], 0))
        copy = pin.Frame(frame.name, joint_map[pj], parent_frame, frame.placement, frame.type,
                         frame.inertia)
        frame_map[fid] = new.addFrame(copy, False)
    return frame_map
