"""Motions of the model held inside its ranges of motion, and smoothed without leaving them.

A ball joint's range is a box on its anatomical angles (``configs/joints.yaml``), and on the
Euler triple nearest to that box (:func:`~ikfusion.model.angle_continuity.nearest_to_ranges`)
a pose inside the ranges has one triple in the box: the box is narrower than a turn and keeps
the middle angle away from +-90 deg. Averages of poses taken on those triples stay in the box
(it is convex), so a motion smoothed there stays inside the ranges and out of the band near
gimbal lock that the ranges exclude; averaged as quaternions, two poses at either edge of a
range (or either side of the lock) average to a pose outside it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..rotations import matrix_to_quat_wxyz, quat_wxyz_to_matrix, wxyz_to_xyzw, xyzw_to_wxyz
from .angle_continuity import nearest_to_ranges
from .human_model import HumanModel


def change_into_range(low: np.ndarray, high: np.ndarray, kappa: np.ndarray) -> np.ndarray:
    """The smallest change ``d`` (..., 3) [rad] of a triple that brings it into its range.

    Args:
        low: (..., 3) the least allowed change of each angle, ``lower - a`` [rad].
        high: (..., 3) the largest, ``upper - a``.
        kappa: (...) the coupling of the first and third angles
            (:func:`~ikfusion.model.angle_continuity.turn_into_range`).

    Returns:
        (..., 3): 0 for a triple inside; the middle angle clamped alone; the first and third
        together, along the edge of their box where the joint turns least
        (``d1^2 + d3^2 + 2 kappa d1 d3``): near gimbal lock an angle held at its limit is
        made up by the other, as the turn of the joint allows.
    """
    middle = np.clip(0.0, low[..., 1], high[..., 1])
    l1, h1, l3, h3 = low[..., 0], high[..., 0], low[..., 2], high[..., 2]
    candidates = []
    for d1 in (l1, h1):
        candidates.append((d1, np.clip(-kappa * d1, l3, h3)))
    for d3 in (l3, h3):
        candidates.append((np.clip(-kappa * d3, l1, h1), d3))
    turns = np.stack([a * a + b * b + 2.0 * kappa * a * b for a, b in candidates])
    best = np.argmin(turns, axis=0)
    first = np.choose(best, [a for a, _ in candidates])
    third = np.choose(best, [b for _, b in candidates])
    inside = (l1 <= 0.0) & (h1 >= 0.0) & (l3 <= 0.0) & (h3 >= 0.0)
    return np.stack([np.where(inside, 0.0, first), middle, np.where(inside, 0.0, third)],
                    axis=-1)


def joint_angles_in_ranges(model: HumanModel, q: npt.ArrayLike) -> np.ndarray:
    """Every ball joint's angles (N, J, 3) [rad] in sequence order, inside its range.

    Each joint's rotation is read on its Euler triple nearest to the range; one beyond the
    range is brought to it by the smallest turn of the joint (:func:`change_into_range`).
    Joints in ``model.ball_joints`` order.
    """
    qs = np.atleast_2d(np.asarray(q, dtype=float))
    out = []
    for joint in model.ball_joints.values():
        spec = joint.spec
        R = quat_wxyz_to_matrix(xyzw_to_wxyz(qs[:, joint.idx_q:joint.idx_q + 4]))
        lower = np.radians([a.lower_deg for a in spec.angles])
        upper = np.radians([a.upper_deg for a in spec.angles])
        a, _ = nearest_to_ranges(spec.angles_from_rotation(R), lower, upper,
                                 spec.axis_coupling)
        kappa = spec.axis_coupling * np.sin(a[:, 1])
        a = a + change_into_range(lower - a, upper - a, kappa)
        out.append(np.clip(a, lower, upper))  # rounding only
    return np.stack(out, axis=1)


def with_joint_angles(model: HumanModel, q: npt.ArrayLike, angles: np.ndarray) -> np.ndarray:
    """A copy of ``q`` (N, nq) whose ball joints take ``angles`` (N, J, 3) [rad]."""
    out = np.array(np.atleast_2d(np.asarray(q, dtype=float)))
    for j, joint in enumerate(model.ball_joints.values()):
        R = joint.spec.rotation(angles[:, j])
        out[:, joint.idx_q:joint.idx_q + 4] = wxyz_to_xyzw(matrix_to_quat_wxyz(R))
    return out


def held_in_ranges(model: HumanModel, q: npt.ArrayLike) -> np.ndarray:
    """``q`` (N, nq) with every ball joint brought into its range (unchanged inside)."""
    qs = np.atleast_2d(np.asarray(q, dtype=float))
    return with_joint_angles(model, qs, joint_angles_in_ranges(model, qs))


def smoothed_in_ranges(model: HumanModel, q: npt.ArrayLike, kernel: np.ndarray) -> np.ndarray:
    """The ball joints of ``q`` (N, nq) smoothed in time inside their ranges.

    Args:
        model: The model.
        q: (N, nq) configurations; joints beyond their range are brought into it first.
        kernel: (2 h + 1,) weights summing to 1 (the series is padded with its end values).

    Returns:
        A copy of ``q`` whose ball joints take the kernel's averages of their in-range angles
        (inside the ranges, as averages of points of a box); other coordinates are unchanged.
    """
    qs = np.atleast_2d(np.asarray(q, dtype=float))
    half = (len(kernel) - 1) // 2
    angles = joint_angles_in_ranges(model, qs)
    flat = np.pad(angles.reshape(len(qs), -1), ((half, half), (0, 0)), mode="edge")
    smooth = np.stack([np.convolve(flat[:, c], kernel, mode="valid")
                       for c in range(flat.shape[1])], axis=1)
    return with_joint_angles(model, qs, smooth.reshape(angles.shape))
