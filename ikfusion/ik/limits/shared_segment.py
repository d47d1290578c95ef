"""Planted points that share one rigid segment: which directions of each can be held.

A rigid segment has six degrees of freedom, and its points move together: with ``v`` and
``omega`` the segment's velocity, a point ``r`` moves at ``v + omega x r``. Two points of
it planted with three rows each give six rows of rank five, since ``(r_2 - r_1) . (v_2 - v_1)
= 0``: their distance cannot change. Three points give nine rows of rank six. Whenever the
anchors are not exactly where the segment's shape puts them (anchors settled apart, the
linearisation of a turning segment: second-order residuals), such dependent rows are
inconsistent and the step's QP is infeasible (a lying body planted on both shoulder blades
needed relaxed constraints frame after frame). The anchors of one segment
settle toward the floor together (:func:`ikfusion.ik.anchor_settling.settled_heights`) and a point
that lands beside planted ones is anchored with their offset
(:func:`ikfusion.ik.foot_pairs.landing_anchors`), so they keep its shape.

The rows are therefore chosen per segment as a rigid body's are: the first planted point of a
segment is held in all three directions (the segment's translation); the second only across
the line from the first point's anchor to its own (two rows: the rotation about the other
two axes); the third only along the normal of the plane of the three anchors (one row: the
rotation about that line). Further points, and a third point on the line of the first two,
add nothing. The held rows are then independent, and holding them holds every point at its
anchor whenever the anchors keep the segment's shape.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..fast_math import true_indices

#: A third point this close to the line of the first two [m] (as the sine of the angle it
#: makes, times its distance) lies on it: it fixes no rotation and gets no row.
COLLINEAR_M = 1e-3


def shared_segment_rows(segments: Sequence[str], active: np.ndarray, anchors: np.ndarray,
                        free_z: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The directions held of each planted point when two or more share a segment.

    Args:
        segments: (k,) the segment carrying each point.
        active: (k,) the planted points.
        anchors: (k, 3) where they are held [m].
        free_z: (k,) points held horizontally only (a rising heel): held as before, never
            counted with the others of their segment.

    Returns:
        None when no segment carries two fully held planted points (every point is then held
        along the world axes). Otherwise ``basis`` (k, 3, 3), each point's orthonormal
        directions as rows (the world axes for a point alone on its segment), and ``held``
        (k, 3), which of them are held (all three for the first point of a segment, the two
        across the line to it for the second, the plane normal for the third; the first two
        axes for a free-z point; nothing for a point not planted).
    """
    groups: dict[str, list[int]] = {}
    for i in true_indices(active & ~free_z):
        groups.setdefault(segments[i], []).append(int(i))
    if all(len(g) < 2 for g in groups.values()):
        return None
    k = len(segments)
    basis = np.repeat(np.eye(3)[None], k, axis=0)
    held = np.repeat(np.asarray(active, dtype=bool)[:, None], 3, axis=1)
    held[:, 2] &= ~np.asarray(free_z, dtype=bool)
    for points in groups.values():
        for order, i in enumerate(points[1:3], start=1):
            basis[i], held[i] = _secondary_rows(anchors[points[0]], anchors[points[1]],
                                                anchors[i], order)
        held[points[3:]] = False
    return basis, held


def _secondary_rows(first: np.ndarray, second: np.ndarray, point: np.ndarray, order: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal directions (3, 3) of the ``order``-th point (1 or 2) and which are held."""
    line = second - first
    axis = line if order == 1 else np.cross(line, point - first)
    length = float(np.linalg.norm(axis))
    scale = float(np.linalg.norm(line)) if order == 2 else 1.0
    if length < COLLINEAR_M * max(scale, 1e-9):  # coincident or collinear: no rotation fixed
        return np.eye(3), np.zeros(3, dtype=bool)
    axis = axis / length
    # two unit directions across ``axis``, from the world axis least along it
    other = np.eye(3)[int(np.argmin(np.abs(axis)))]
    across = np.cross(axis, other)
    across /= np.linalg.norm(across)
    third = np.cross(axis, across)
    if order == 1:  # across the line: the two directions perpendicular to it
        return np.array([across, third, axis]), np.array([True, True, False])
    return np.array([axis, across, third]), np.array([True, False, False])
