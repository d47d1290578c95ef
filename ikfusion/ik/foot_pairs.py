"""The two feet of the contact points: which points the other foot holds, how far they disagree.

Helpers of :mod:`.contacts`; a point's foot is given by :class:`FootLayout` ``same_foot``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from ..model.topology import FootLayout
from .fast_math import any_true, mean_rows, row_norms, true_indices
from .point_masks import layout_memo


def other_foot(layout: FootLayout, mask: np.ndarray) -> np.ndarray:
    """Per point: does the *other* foot have a point in ``mask`` (k,) bool?

    A boolean matrix product: ``any_j(other_foot[i, j] and mask[j])``, once per pattern of
    ``mask`` (:mod:`.point_masks`; read-only).
    """
    return layout_memo(layout, "other_foot", _other_foot)(mask)


def _other_foot(layout: FootLayout, mask: np.ndarray) -> np.ndarray:
    """:func:`other_foot`'s product."""
    return np.asarray(layout.other_foot @ mask)


def landing_anchors(layout: FootLayout, active: np.ndarray, anchors: np.ndarray,
                     p_solved: np.ndarray, enter: np.ndarray) -> np.ndarray:
    """Anchors [m] of the ``enter`` points: where they were solved, shifted with their foot.

    A point that lands while another point of its foot is planted is anchored consistently
    with that foot's anchors (where it was solved plus the foot's mean anchor - solved
    offset), so the foot's anchors keep its shape even when the planted points were not held
    exactly (a relaxed frame, a touch-down offset of the drift correction).
    """
    same = layout.same_foot
    out = p_solved[enter].copy()
    for row, i in enumerate(true_indices(enter)):
        planted = same[i] & active
        if any_true(planted):
            out[row] += mean_rows(anchors[planted] - p_solved[planted])
    return out


def drift_from_other_foot(layout: FootLayout, active: np.ndarray, anchors: np.ndarray,
                          p_sensed: np.ndarray) -> np.ndarray:
    """How far each planted point is pulled from its anchor by the other foot.

    The sensed pose is aligned on the planted points of the *other* foot; the horizontal
    distance of the point from its anchor then says how much the two feet disagree [m] (0 when
    the other foot has no planted point).
    """
    pairs = layout_memo(layout, "planted_pairs", _planted_pairs)(active)
    if pairs is None:  # the usual case: one foot planted
        return _no_drift(len(active))[0]
    others, has, count = pairs
    offset = (others @ (anchors - p_sensed)) / count
    return np.where(has, row_norms((p_sensed + offset - anchors)[:, :2]), 0.0)


def drifting_points(layout: FootLayout, active: np.ndarray, anchors: np.ndarray,
                    p_sensed: np.ndarray, limit: float, rows: Sequence[int]) -> int:
    """The points of ``rows`` (bits) that :func:`drift_from_other_foot` puts over ``limit`` [m].

    ``bits.of(drift_from_other_foot(...) > limit)`` on ``rows`` (:mod:`.point_bits`), the same
    numbers: the offset by NumPy, each row's horizontal distance as Python floats, the products,
    sum and square root of ``row_norms`` in its order (IEEE; NaN compares False), without the
    NumPy calls on the rows that are not asked (a frame on two feet asks the planted points).
    """
    pairs = layout_memo(layout, "planted_pairs", _planted_pairs)(active)
    if pairs is None:  # no drift: 0 everywhere
        return sum(1 << i for i in rows) if 0.0 > limit else 0
    others, has, count = pairs
    offset = (others @ (anchors - p_sensed)) / count
    away, has_other = (p_sensed + offset - anchors).tolist(), has.tolist()
    out = 0
    for i in rows:
        x, y = away[i][0], away[i][1]
        if (math.sqrt(x * x + y * y) if has_other[i] else 0.0) > limit:
            out |= 1 << i
    return out


def other_foot_age(layout: FootLayout, active: np.ndarray, age: np.ndarray) -> np.ndarray:
    """The longest contact age [s] of the other foot's planted points (+inf when none).

    ``active``: (k,) the planted points; ``age``: (k,) how long each has been planted [s].
    """
    pairs = layout_memo(layout, "planted_pairs", _planted_pairs)(active)
    if pairs is None:
        return _no_drift(len(active))[1]
    others, has, _ = pairs
    return np.where(has, np.where(others, age[None, :], -np.inf).max(axis=1), np.inf)


def _planted_pairs(layout: FootLayout, active: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """:func:`drift_from_other_foot`'s pairs of planted points, once per pattern of ``active``.

    None while one foot holds the planted points, else the (k, k) planted points of the other
    foot of each point (row i; 1.0 or 0.0, the matrix the product takes), whether it has any
    (k,) and how many (k, 1), at least 1.
    """
    if not any_true(active & other_foot(layout, active)):
        return None
    others = active[:, None] & active[None, :] & layout.other_foot  # row i: the other foot's
    count = others.sum(axis=1)
    return others.astype(float), count > 0, np.maximum(count, 1)[:, None]


@functools.cache
def _no_drift(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Of :func:`drift_from_other_foot` without two planted feet: no drift, no other age.

    (Read-only, one pair per number of points.)
    """
    drift, other_age = np.zeros(k), np.full(k, np.inf)
    drift.setflags(write=False)
    other_age.setflags(write=False)
    return drift, other_age
