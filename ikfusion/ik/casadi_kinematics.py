"""Pinocchio's forward kinematics and frame Jacobians written as a CasADi ``SX`` graph.

The graph follows the Pinocchio model exactly (same joint placements and joint types: free-flyer,
spherical, revolute); joint and frame placements are symbolic inputs (the *geometry*), so bodies
of every size share one graph. Used by :mod:`.compiled` to build the step function, with
:func:`angular_objective`, which sums rows on angular Jacobians along the kinematic tree.

Tangent steps follow Pinocchio: a free-flyer moves by ``M exp(v)`` in its local frame, a
spherical joint by ``R exp(w)``, a revolute joint by adding to its angle.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import pinocchio as pin

from ..rotations_casadi import quat_xyzw_to_matrix, rotation_about
from .compiled_blocks import dot_block_function, segment_function, spherical_joint_function


def symbolic_placements(geometry: ca.SX, n_joints: int, frames: list[int]) -> dict:
    """Symbolic placements: ("joint", j) and ("frame", f) -> (R (3, 3), p (3,))."""
    out = {}
    keys = [("joint", j) for j in range(1, n_joints + 1)] + [("frame", f) for f in frames]
    for n, key in enumerate(keys):
        g = geometry[12 * n:12 * n + 12]
        out[key] = (ca.reshape(g[:9], 3, 3), g[9:12])
    return out


def geometry_vector(model: pin.Model, frames: list[int]) -> np.ndarray:
    """The numbers :func:`symbolic_placements` stands for.

    Every joint placement, then those of ``frames``: each rotation column-major, then its
    translation [m].
    """
    placements = [model.jointPlacements[j] for j in range(1, model.njoints)]
    placements += [model.frames[f].placement for f in frames]
    return np.concatenate([np.concatenate([M.rotation.T.reshape(-1), M.translation])
                           for M in placements])


def forward(model: pin.Model, q: ca.SX, placements: dict) -> tuple[list, list, dict]:
    """World rotation and origin of every joint frame, and each tangent column's motion.

    Returns ``axes``: tangent index -> ("angular", world axis) or ("linear", world axis),
    the world-frame motion of the joint frame per unit step of that coordinate.
    """
    rotations: list = [ca.DM.eye(3)]
    translations: list = [ca.DM.zeros(3)]
    axes: dict[int, tuple[str, ca.SX]] = {}
    for j in range(1, model.njoints):
        joint = model.joints[j]
        iq, iv = model.idx_qs[j], model.idx_vs[j]
        kind = joint.shortname()
        R_M, p_M = placements[("joint", j)]
        parent = model.parents[j]
        if kind == "JointModelSpherical" and parent > 0:  # one body, called per joint
            R_world, p_world = spherical_joint_function()(
                rotations[parent], translations[parent], R_M, p_M, q[iq:iq + 4])
            for k in range(3):
                axes[iv + k] = ("angular", R_world[:, k])
            rotations.append(R_world)
            translations.append(p_world)
            continue
        R_parent = rotations[parent] @ R_M
        p_parent = translations[parent] + rotations[parent] @ p_M
        if kind == "JointModelFreeFlyer":
            R_local = quat_xyzw_to_matrix(q[iq + 3:iq + 7])
            p_local = q[iq:iq + 3]
            R_world = R_parent @ R_local
            for k in range(3):
                axes[iv + k] = ("linear", R_world[:, k])
                axes[iv + 3 + k] = ("angular", R_world[:, k])
        elif kind == "JointModelSpherical":
            R_local = quat_xyzw_to_matrix(q[iq:iq + 4])
            p_local = ca.SX.zeros(3)
            R_world = R_parent @ R_local
            for k in range(3):
                axes[iv + k] = ("angular", R_world[:, k])
        elif kind in ("JointModelRX", "JointModelRY", "JointModelRZ",
                      "JointModelRevoluteUnaligned"):
            axis = (np.eye(3)[int(kind[-1] == "Y") + 2 * int(kind[-1] == "Z")]
                    if kind != "JointModelRevoluteUnaligned"
                    else np.asarray(joint.extract().axis))
            R_local = rotation_about(axis, q[iq])
            p_local = ca.SX.zeros(3)
            R_world = R_parent @ R_local
            axes[iv] = ("angular", R_world @ ca.DM(axis))
        else:
            raise NotImplementedError(f"joint type {kind} is not compiled")
        rotations.append(R_world)
        translations.append(p_parent + R_parent @ p_local)
    return rotations, translations, axes


def jacobian(model: pin.Model, fid: int, axes: dict, translations: list,
              point: ca.SX | None) -> ca.SX:
    """Geometric Jacobian (6, nv) of a frame in the world frame.

    Linear rows (of ``point``) first, then angular rows; only the columns of the frame's
    supporting joints are filled.
    """
    J = ca.SX(6, model.nv)
    joint = model.frames[fid].parentJoint
    for j in model.supports[joint]:
        if j == 0:
            continue
        origin = translations[j]
        for iv in range(model.idx_vs[j], model.idx_vs[j] + model.nvs[j]):
            kind, axis = axes[iv]
            if kind == "linear":
                J[0:3, iv] = axis
            else:
                J[3:6, iv] = axis
                if point is not None:
                    J[0:3, iv] = ca.cross(axis, point - origin)
    return J


def frame_pose(model: pin.Model, fid: int, rotations: list, translations: list,
               placements: dict) -> tuple:
    """World rotation and origin of frame ``fid`` from the joint frames of :func:`forward`."""
    j = model.frames[fid].parentJoint
    R_M, p_M = placements[("frame", fid)]
    return rotations[j] @ R_M, translations[j] + rotations[j] @ p_M


def orientation_terms(model: pin.Model, segment_frames: Sequence[int], targets: ca.SX,
                      w_orient: ca.SX, kinematics: tuple[list, list, dict], placements: dict
                      ) -> tuple[list, list, list, list[list[int]]]:
    """Per tracked segment: ``e_orient`` (3), ``K = M^T W M`` (3, 3), ``g = M^T W e`` (3), dofs.

    ``e = log(R_world_segment R_world_target^T)`` [rad] with ``M = Jl^-1(e)`` (so that
    ``J_orient = M J_angular``), ``W = diag(w_orient)`` of the segment's three rows, and its
    angular tangent columns (those of its supporting joints) for :func:`angular_objective`.
    ``targets`` (9k) are the column-major ``R_world_target``; ``kinematics`` is what
    :func:`forward` returns.
    """
    rotations, translations, axes = kinematics
    e_orient, K_orient, g_orient, dofs = [], [], [], []
    segment = segment_function()  # one body in the generated code, called per segment
    for n, fid in enumerate(segment_frames):  # J_orient = Jl^-1(e) J_angular
        R_M = placements[("frame", fid)][0]  # the frame's pose taken in the call
        e, K, g = segment(rotations[model.frames[fid].parentJoint], R_M,
                          ca.reshape(targets[9 * n:9 * n + 9], 3, 3), w_orient[3 * n:3 * n + 3])
        e_orient.append(e)
        K_orient.append(K)
        g_orient.append(g)
        dofs.append([iv for j in model.supports[model.frames[fid].parentJoint] if j
                     for iv in range(model.idx_vs[j], model.idx_vs[j] + model.nvs[j])
                     if axes[iv][0] == "angular"])
    return e_orient, K_orient, g_orient, dofs


def angular_objective(K: list[ca.SX], g: list[ca.SX], dofs: list[list[int]], axes: dict,
                      nv: int, triples: Sequence[int] = ()) -> tuple[ca.SX, ca.SX]:
    """``sum_s A_s^T K_s A_s`` (lower triangle) and ``sum_s A_s^T g_s`` over segments ``s``.

    ``A_s`` (3, nv) is segment ``s``'s angular Jacobian: the world ``axes`` of its supporting
    joints' rotation steps ``dofs[s]``, zero elsewhere. A joint's axis is the same column for
    every segment it carries, so entry ``(i, j)`` is ``a_i^T (sum of K_s over the segments
    carrying both) a_j``: the 3x3 matrices ``K_s`` (3, 3) are summed once per set of segments
    instead of forming every segment's product (a few times fewer operations). ``g_s`` (3,).
    ``triples``: the first columns of joints whose three rotation steps are columns ``i..i+2``
    (spherical joints, the free-flyer's rotation): the entries of two such joints are one call
    of :func:`.compiled_blocks.dot_block_function` (the same products, one body in the code).
    """
    carried: dict[int, set[int]] = {}
    for s, columns in enumerate(dofs):
        for iv in columns:
            carried.setdefault(iv, set()).add(s)
    groups = {iv: frozenset(segments) for iv, segments in sorted(carried.items())}
    sums: dict[frozenset[int], tuple[ca.SX, ca.SX]] = {}

    def summed(group: frozenset[int]) -> tuple[ca.SX, ca.SX]:
        if group not in sums:
            members = sorted(group)
            sums[group] = (sum((K[s] for s in members[1:]), K[members[0]]),
                           sum((g[s] for s in members[1:]), g[members[0]]))
        return sums[group]

    H, c = ca.SX(nv, nv), ca.SX(nv, 1)
    u = {}  # (sum of K over the segments of i) a_i
    for iv, group in groups.items():
        S, total = summed(group)
        c[iv] = ca.dot(axes[iv][1], total)
        u[iv] = S @ axes[iv][1]
    blocks = [i for i in triples if i in groups]
    done = _dot_blocks(H, blocks, groups, axes, u)
    order = list(groups)
    for n, iv in enumerate(order):
        for iu in order[:n + 1]:  # iu <= iv: the lower triangle
            if (iv, iu) in done:
                continue
            both = groups[iv] & groups[iu]
            if both == groups[iv]:
                H[iv, iu] = ca.dot(axes[iu][1], u[iv])
            elif both == groups[iu]:
                H[iv, iu] = ca.dot(axes[iv][1], u[iu])
            elif both:
                H[iv, iu] = ca.dot(axes[iv][1], summed(both)[0] @ axes[iu][1])
    return H, c


def _dot_blocks(H: ca.SX, firsts: list[int], groups: dict, axes: dict, u: dict
                ) -> set[tuple[int, int]]:
    """Write the lower-triangle entries of :func:`angular_objective` between two joints' triples.

    Each 3x3 block whose entries are ``dot(a_j, u_i)`` or ``dot(a_i, u_j)`` is one call of
    :func:`.compiled_blocks.dot_block_function` (the same products and sums; ``a . b`` and
    ``b . a`` are the same numbers). Returns the entries ``(i, j)`` written.
    """
    def columns(vectors: dict, first: int) -> ca.SX:
        return ca.horzcat(*(vectors[first + k] for k in range(3)))

    a = {iv: axis for iv, (_, axis) in axes.items()}
    done = set()
    for n, first in enumerate(firsts):
        for second in firsts[:n + 1]:
            both = groups[first] & groups[second]
            if both == groups[first]:  # H[i, j] = dot(a_j, u_i)
                block = dot_block_function()(columns(u, first), columns(a, second))
            elif both == groups[second]:  # H[i, j] = dot(a_i, u_j)
                block = dot_block_function()(columns(a, first), columns(u, second))
            else:
                continue
            for v in range(3):
                for w in range(3 if second < first else v + 1):
                    H[first + v, second + w] = block[v, w]
                    done.add((first + v, second + w))
    return done


def angular_triples(model: pin.Model) -> list[int]:
    """The first tangent columns of the joints rotating about three world axes in a row.

    Spherical joints (their three columns) and the free-flyer (its last three), as
    :func:`forward` lays out ``axes``.
    """
    kinds = {"JointModelSpherical": 0, "JointModelFreeFlyer": 3}
    return [model.idx_vs[j] + kinds[model.joints[j].shortname()]
            for j in range(1, model.njoints) if model.joints[j].shortname() in kinds]
