"""World positions and linear Jacobians of a fixed set of points as one CasADi function.

Built beside the step function of :mod:`.compiled` (the same symbols, compiled into the same
library). The contact points are asked for several times per frame (the projection onto the
contacts, the touch-down, the floor): one call of this function per configuration gives all of
them, instead of one Pinocchio call per point.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import pinocchio as pin

from .casadi_kinematics import frame_pose, jacobian


def point_kinematics(model: pin.Model, frames: Sequence[int], rotations: list,
                     translations: list, placements: dict, axes: dict
                     ) -> tuple[list[ca.SX], list[ca.SX]]:
    """``p_world_point`` (3,) [m] and the linear Jacobian (3, nv) of each frame of ``frames``.

    The Jacobian rows are those of Pinocchio's ``LOCAL_WORLD_ALIGNED`` frame Jacobian (the
    world velocity of the frame origin per unit tangent step). ``rotations``, ``translations``
    and ``axes`` are the joint frames of :func:`.casadi_kinematics.forward`, ``placements``
    those of :func:`.casadi_kinematics.symbolic_placements`.
    """
    p_points, J_points = [], []
    for fid in frames:
        _, p = frame_pose(model, fid, rotations, translations, placements)
        p_points.append(p)
        J_points.append(jacobian(model, fid, axes, translations, p)[:3, :])
    return p_points, J_points


def points_function(model: pin.Model, frames: Sequence[int], name: str, q: ca.SX,
                    geometry: ca.SX, placements: dict, rotations: list, translations: list,
                    axes: dict) -> ca.Function:
    """``name(q, geometry) -> (p_points (3n) [m], J_points (3n, nv))`` of ``frames`` (n).

    The symbols ``q``, ``geometry``, the ``placements`` they make and the joint frames of
    :func:`.casadi_kinematics.forward` are those of the step function.
    """
    p_points, J_points = point_kinematics(model, frames, rotations, translations, placements,
                                          axes)
    return ca.Function(name, [q, geometry],
                       [ca.vertcat(*p_points) if p_points else ca.SX(0, 1),
                        ca.vertcat(*J_points) if J_points else ca.SX(0, model.nv)],
                       ["q", "geometry"], ["p_points", "J_points"])


def point_rows(site_frames: Sequence[int], points: Sequence[int]) -> list[int] | None:
    """The rows of ``points`` among the sites ``site_frames``, then the last site's (the root).

    The sites of the step function :func:`rows_only` keeps; None without points or when one is
    not a site.
    """
    if not points or not set(points) <= set(site_frames):
        return None
    return [list(site_frames).index(f) for f in points] + [len(site_frames) - 1]


def rows_only(outputs: Sequence[ca.SX], rows: Sequence[int]) -> list[ca.SX]:
    """The step function's outputs with ``p_sites`` and ``J_sites`` (5 and 6) cut to ``rows``.

    The same expressions (so the same numbers bit for bit) for the sites a step weighing no
    site target reads (the contact points and the root): a tenth fewer instructions.
    """
    index = [3 * r + k for r in rows for k in range(3)]
    return [o[index] if i == 5 else o[index, :] if i == 6 else o for i, o in enumerate(outputs)]
