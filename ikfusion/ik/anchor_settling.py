"""Anchors above the floor settling down to it, the planted points of one rigid segment as one.

A helper of :mod:`.contacts` (``touch_down``) and :mod:`.contact_tracker`; heights in metres,
world z up.
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from .fast_math import any_true

if TYPE_CHECKING:
    from ..model.topology import FootLayout


def settled_heights(z: np.ndarray, active: np.ndarray, same_segment: np.ndarray, drop: float,
                    floor_z: float, shares_segment: np.ndarray | None = None) -> np.ndarray:
    """Anchor heights (k,) [m] lowered by at most ``drop`` [m] toward the floor ``floor_z`` [m].

    A point settles straight down until it reaches the floor. Planted points that share a
    rigid segment (``same_segment`` (k, k), e.g. both shoulder blades of a lying body) settle
    together by the least room above the floor among them: the segment translates down and its
    anchors keep its shape. One settling alone next to another on the floor would tilt the
    segment about that one, and its point would slide sideways by ``dz^2 / (2 d)`` (a shoulder
    blade planted 24 mm up, 17 cm from the other: 1.8 mm).

    Args:
        z: (k,) anchor heights [m].
        active: (k,) planted points.
        same_segment: (k, k) points on one rigid segment.
        drop: How far an anchor settles at most this frame [m].
        floor_z: Floor height [m].
        shares_segment: (k,) points with another point on their segment
            (:attr:`FootLayout.shares_segment`), when the caller has it: while none of them
            is planted every point settles alone (the usual case, feet only).

    Returns:
        The settled heights; ``z`` itself when every anchor is on the floor already.
    """
    if drop >= 0.0 and z.tobytes() == _on_floor(len(z), floor_z, math.copysign(1.0, floor_z)):
        return z  # every anchor on the floor (bit for bit): nothing settles (the usual frame)
    own = np.minimum(np.maximum(z - floor_z, 0.0), drop)  # np.clip's result, without its wrapper
    if shares_segment is not None and not any_true(active & shares_segment):
        return np.maximum(z - own, floor_z)  # each point its own segment's least room
    together = same_segment & active[:, None] & active[None, :]
    shared = np.where(together, own[None, :], np.inf).min(axis=1)  # inf: no planted partner
    return np.maximum(z - np.minimum(own, shared), floor_z)


def settled_anchors(anchors: np.ndarray, planted: np.ndarray, drop: float, floor_z: float,
                    layout: FootLayout) -> np.ndarray:
    """The anchors (k, 3) [m] with their heights settled (:func:`settled_heights`).

    ``planted`` (k,): the planted points (those of one segment settle together, ``layout``'s
    segments); ``drop``, ``floor_z`` [m] as there. ``anchors`` itself when no height changed,
    bit for bit (a state's arrays are never written to), else a new array.
    """
    z = anchors[:, 2]
    settled = settled_heights(z, planted, layout.same_segment, drop, floor_z,
                              layout.shares_segment)
    if settled is z or settled.tobytes() == z.tobytes():
        return anchors
    out = anchors.copy()
    out[:, 2] = settled
    return out


@functools.cache
def _on_floor(k: int, floor_z: float, sign: float) -> bytes:
    """The bytes of ``k`` heights [m] at ``floor_z`` exactly (:func:`settled_heights`'s test).

    ``sign``: ``floor_z``'s (a floor at -0.0 equals one at 0.0 as a key, not in its bytes).
    """
    return np.full(k, floor_z, dtype=float).tobytes()


def risen_heights(z: np.ndarray, z_solved: np.ndarray, risen: np.ndarray,
                  floor_z: float) -> np.ndarray:
    """Anchor heights (k,) [m] with those of the ``risen`` points at ``z_solved`` (k,) [m].

    A planted heel held horizontally only (rising as its foot rolls toe-down) is not held in
    height, and its anchor settles to the floor under it. When it is held in height again,
    its anchor is where it rose to (the caller passes one settling step under where it was
    solved), on or above ``floor_z`` [m], and settles from there (:func:`settled_heights`):
    a floor anchor under a heel held 7 mm up by a foot its IMU pitched a few tenths of a degree
    toe-down pulled the heel down in one frame when the pitch fell back, and the ankle popped
    (gen-jumps landings, 1.2 deg).
    """
    return np.where(risen, np.maximum(z_solved, floor_z), z)


def held_again(anchors: np.ndarray, z_solved: np.ndarray, again: np.ndarray, drop: float,
               floor_z: float) -> np.ndarray:
    """The anchors (k, 3) [m] once the heels ``again`` (k,) that rose are held in height again.

    Each is anchored ``drop`` [m] (one settling step) under where it was solved in the last
    frame, ``z_solved`` (k,) [m], on or above ``floor_z`` [m] (:func:`risen_heights`), and
    settles on from there; the other anchors are unchanged (a new array).
    """
    out = anchors.copy()
    out[:, 2] = risen_heights(out[:, 2], z_solved - drop, again, floor_z)
    return out
