"""Continuous anatomical joint angles: no +-360 deg wraps, no jumps between Euler branches.

A joint's rotation is an intrinsic Euler (Tait-Bryan) sequence of three angles
``(a1, a2, a3)`` (``configs/joints.yaml``). Every rotation has two such triples:

    (a1, a2, a3)  and  (a1 + pi, pi - a2, a3 + pi)      (each angle modulo 2 pi)

(signs of the anatomical angles do not change this: ``s * pi`` equals ``pi`` modulo 2 pi).
The principal decomposition keeps the middle angle in [-90, 90] deg and the others in
(-180, 180] deg; a motion through ``|a2| = 90`` deg (arms overhead, high kicks, spins) or
through 180 deg then jumps by about 180 or 360 deg in one frame although the body moved a little.
Here each frame takes, of the two triples and their 2 pi shifts, the one closest to a reference:
the previous frame for a series (:func:`continuous_series`, causal: frame k depends on frames
up to k only), or any reference triple (:func:`nearest_equivalent`, e.g. the truth's angles at
the same time, so that an error compares like with like).

All angles here are in radians with the three angles of a joint on the last axis in sequence
order, unless a function says degrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from .continuity_kernel import continuous_in_place
from .joints import JointSpec

_TURN = 2.0 * np.pi
_OTHER_SIGNS = np.array([1.0, -1.0, 1.0])  # the other triple is (a1 + pi, pi - a2, a3 + pi)


def equivalent_triple(angles: npt.ArrayLike) -> np.ndarray:
    """The other Euler triple of the same rotation, ``(a1 + pi, pi - a2, a3 + pi)`` [rad].

    Args:
        angles: (..., 3) angles in sequence order [rad].

    Returns:
        (..., 3), not wrapped to any interval.
    """
    a = np.asarray(angles, dtype=float)
    return np.stack([a[..., 0] + np.pi, np.pi - a[..., 1], a[..., 2] + np.pi], axis=-1)


def wrap_near(angles: npt.ArrayLike, reference: npt.ArrayLike) -> np.ndarray:
    """``angles`` shifted by whole turns to lie within pi of ``reference`` [rad] (elementwise)."""
    a = np.asarray(angles, dtype=float)
    return a + _TURN * np.round((np.asarray(reference, dtype=float) - a) / _TURN)


def nearest_equivalent(angles: npt.ArrayLike,
                       reference: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The triple of the same rotation as ``angles`` closest to ``reference``.

    Args:
        angles: (..., 3) any Euler triple per joint [rad], e.g. the principal decomposition.
        reference: (..., 3) the triple to stay close to [rad] (e.g. the previous frame's).

    Returns:
        The chosen triples (..., 3) [rad] and a mask (...) of those on the other branch than
        ``angles`` (there the middle angle's rate changes sign: ``d a2' = -d a2``).
    """
    ref = np.asarray(reference, dtype=float)
    same = wrap_near(angles, ref)
    other = wrap_near(equivalent_triple(angles), ref)
    flipped = np.sum((other - ref) ** 2, axis=-1) < np.sum((same - ref) ** 2, axis=-1)
    return np.where(flipped[..., None], other, same), flipped


def continuous_series(angles: npt.ArrayLike) -> np.ndarray:
    """A series of joint angles made continuous frame by frame (causal).

    The first frame is kept; every later frame takes the triple of its rotation closest to the
    previous frame's result (:func:`nearest_equivalent`). A joint whose angles hold NaN in a
    frame is kept as it is there and does not become the reference.

    Args:
        angles: (N, ..., 3) angles per frame in sequence order [rad].

    Returns:
        (N, ..., 3) [rad], the same rotations.
    """
    a = np.array(angles, dtype=float, order="C")
    if len(a) <= 1:
        return a
    flat = a.reshape(len(a), -1, 3)
    if continuous_in_place(flat):  # the C kernel: the same rule, the same numbers
        return a
    whole = np.isfinite(flat).all(axis=(0, 2))  # joints finite in every frame
    for j in np.flatnonzero(whole):  # one by one, contiguous: faster than all at once
        flat[:, j] = _continuous_finite(np.ascontiguousarray(flat[:, j])[:, None])[:, 0]
    for j in np.flatnonzero(~whole):
        finite = np.flatnonzero(np.isfinite(flat[:, j]).all(axis=1))
        if len(finite) > 1:  # rows holding NaN are kept as they are and are no reference
            flat[finite, j] = _continuous_finite(flat[finite, j][:, None])[:, 0]
    return flat.reshape(a.shape)


def _continuous_finite(x: np.ndarray) -> np.ndarray:
    """:func:`continuous_series` of joints' finite (M, J, 3) angles [rad], all frames at once.

    Whole turns do not change which branch is nearer, and the two branches are mirror images
    (the wrapped distance of ``a`` to the other triple of ``b`` equals that of the other triple
    of ``a`` to ``b``): frame k so changes branch relative to frame k-1 exactly when the other
    triple of its raw angles lies nearer to frame k-1's raw angles, and its turn count is the
    previous one plus the rounded step. The result is then checked against the frame-by-frame
    rule in the same floating-point operations; from a frame where they differ (a near-tie in
    rounding) the frame-by-frame rule is run on, for that joint. The result is so identical to
    that rule's. Every operation is elementwise per joint: the joints do not mix.
    """
    other = np.stack([x[..., 0] + math.pi, math.pi - x[..., 1], x[..., 2] + math.pi], axis=-1)
    step_same = _wrapped_squares(x[1:] - x[:-1])
    step_other = _wrapped_squares(other[1:] - x[:-1])
    flipped = np.concatenate([np.zeros((1, x.shape[1]), dtype=np.int64),
                              np.cumsum(step_other < step_same, axis=0) % 2]).astype(bool)
    chosen = np.where(flipped[..., None], other, x)
    turns = np.zeros(x.shape, dtype=np.int64)
    turns[1:] = np.cumsum(np.rint((chosen[:-1] - chosen[1:]) / _TURN).astype(np.int64), axis=0)
    out = chosen + _TURN * turns
    out[0] = x[0]
    # The frame-by-frame rule with each frame's reference taken from ``out``.
    ref = out[:-1]
    same = x[1:] + _TURN * np.rint((ref - x[1:]) / _TURN)
    near_other = other[1:] + _TURN * np.rint((ref - other[1:]) / _TURN)
    pick_other = _summed_squares(near_other - ref) < _summed_squares(same - ref)
    rule = np.where(pick_other[..., None], near_other, same)
    differ = (rule != out[1:]).any(axis=-1)
    for j in np.flatnonzero(differ.any(axis=0)):
        k = int(np.flatnonzero(differ[:, j])[0]) + 1
        out[k - 1:, j] = _continuous_triples(out[k - 1:k, j].tolist() + x[k:, j].tolist())
    return out


def _wrapped_squares(d: np.ndarray) -> np.ndarray:
    """Sum over the last axis of the squares of ``d`` [rad] wrapped into [-pi, pi]."""
    return _summed_squares(d - _TURN * np.rint(d / _TURN))


def _summed_squares(d: np.ndarray) -> np.ndarray:
    """``d0**2 + d1**2 + d2**2`` over the last axis, added in that order."""
    return d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2


def _continuous_triples(rows: list[list[float]]) -> list[list[float]]:
    """:func:`continuous_series` of one joint's (N, 3) angles given as lists [rad]."""
    out = [rows[0]]
    previous = rows[0]
    known = all(math.isfinite(v) for v in previous)
    for row in rows[1:]:
        if not known or not all(math.isfinite(v) for v in row):
            out.append(row)
            if not known and all(math.isfinite(v) for v in row):
                previous, known = row, True
            continue
        a1, a2, a3 = row
        same = [_near(a1, previous[0]), _near(a2, previous[1]), _near(a3, previous[2])]
        other = [_near(a1 + math.pi, previous[0]), _near(math.pi - a2, previous[1]),
                 _near(a3 + math.pi, previous[2])]
        d_same = sum((v - r) ** 2 for v, r in zip(same, previous))
        d_other = sum((v - r) ** 2 for v, r in zip(other, previous))
        previous = other if d_other < d_same else same
        out.append(previous)
    return out


def _near(angle: float, reference: float) -> float:
    """``angle`` shifted by whole turns to lie within pi of ``reference`` [rad]."""
    return angle + _TURN * round((reference - angle) / _TURN)


def sequence_columns(columns: Sequence[str],
                     specs: Mapping[str, JointSpec]) -> np.ndarray:
    """Indices into ``columns`` of each joint's three angles in sequence order, shape (J, 3).

    Only joints of ``specs`` whose three columns (``<joint>_flex`` ...) are all present count.
    """
    where = {c: i for i, c in enumerate(columns)}
    rows = []
    for spec in specs.values():
        names = [spec.column(a.name) for a in spec.angles]
        if all(n in where for n in names):
            rows.append([where[n] for n in names])
    return np.array(rows, dtype=int).reshape(-1, 3)


def continuous_columns_deg(values_deg: npt.ArrayLike, columns: Sequence[str],
                           specs: Mapping[str, JointSpec]) -> np.ndarray:
    """:func:`continuous_series` of a table of angles [deg] with named columns.

    Args:
        values_deg: (N, C) angles [deg], columns like ``jRightHip_flex``.
        columns: (C,) the column names.
        specs: The joints, for each one's Euler sequence.

    Returns:
        (N, C) [deg]; columns of no complete joint are returned as they are.
    """
    out = np.array(values_deg, dtype=float)
    index = sequence_columns(columns, specs)
    if index.size:
        out[:, index] = np.degrees(continuous_series(np.radians(out[:, index])))
    return out


def nearest_columns_deg(values_deg: npt.ArrayLike, reference_deg: npt.ArrayLike,
                        columns: Sequence[str], specs: Mapping[str, JointSpec]) -> np.ndarray:
    """Per row, each joint's triple of ``values_deg`` closest to ``reference_deg`` [deg].

    Args:
        values_deg: (N, C) angles [deg].
        reference_deg: (N, C) reference angles at the same rows [deg] (e.g. the truth).
        columns: (C,) the column names of both.
        specs: The joints, for each one's Euler sequence.

    Returns:
        (N, C) [deg], the same rotations as ``values_deg``.
    """
    out = np.array(values_deg, dtype=float)
    index = sequence_columns(columns, specs)
    if index.size:
        chosen, _ = nearest_equivalent(np.radians(out[:, index]),
                                       np.radians(np.asarray(reference_deg, dtype=float)[:, index]))
        out[:, index] = np.degrees(chosen)
    return out


def nearest_to_ranges(angles: npt.ArrayLike, lower: npt.ArrayLike, upper: npt.ArrayLike,
                      coupling: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The triple of each rotation that lies closest to its range of motion.

    The first and third angles are taken within half a turn of the middle of their range (the
    cut sits in the middle of the excluded arc, not at +-180 deg), and of the two Euler branches
    the one that the smaller turn of the joint brings into its range is kept
    (:func:`turn_into_range`). A pose beyond a limit is so measured from the limit it crossed,
    not from the opposite one across the wrap: a hip flexed to 185 deg is 55 deg beyond its
    130 deg limit, not 140 deg below -35 deg. Near gimbal lock the turn is not the angles'
    distance: a shoulder at 74 deg rotation, 21 deg past its extension limit with its abduction
    21 deg up, is 6 deg of turn from its range, while its other branch (rotation 106 deg) is 21
    deg away; measured angle by angle, that other branch looked nearer, and the solve was thrown
    through the lock to a pose 20 deg off the arm.

    Args:
        angles: (..., 3) any triple per joint [rad] in sequence order.
        lower: (..., 3) lower limits [rad].
        upper: (..., 3) upper limits [rad].
        coupling: (...) each joint's :attr:`~ikfusion.model.joints.JointSpec.axis_coupling`.

    Returns:
        The chosen triples (..., 3) [rad] and the mask (...) of those on the other branch
        (their middle angle's rate has the opposite sign).
    """
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    a = np.asarray(angles, dtype=float)
    # Both branches at once (few NumPy calls: this runs on every step of every frame): the
    # triple itself and its equivalent (a1 + pi, pi - a2, a3 + pi), each wrapped near the
    # centre of the range (sin(pi - a2) = sin(a2): both share the coupling of their axes).
    both = np.concatenate([a[None], (a * _OTHER_SIGNS + np.pi)[None]])
    both += _TURN * np.rint((0.5 * (lo + hi) - both) / _TURN)  # rint: np.round's halves
    kappa = np.asarray(coupling, dtype=float) * np.sin(a[..., 1])
    outside = turn_into_range(lo - both, hi - both, kappa)
    flipped = outside[1] < outside[0]
    return np.where(flipped[..., None], both[1], both[0]), flipped


def turn_into_range(low: np.ndarray, high: np.ndarray, kappa: np.ndarray) -> np.ndarray:
    """Squared turn [rad^2] of the smallest change of a triple that brings it into its range.

    The change ``d`` of the angles must lie in the box ``low <= d <= high`` (``lower - a``,
    ``upper - a``); it turns the joint by ``d1^2 + d2^2 + d3^2 + 2 kappa d1 d3`` to first order
    (see :attr:`~ikfusion.model.joints.JointSpec.axis_coupling`, ``kappa = c sin(a2)``). The
    middle angle is apart: its own distance. For the first and third, the least of that convex
    form over the box is 0 when the box holds d = 0, otherwise on one of its four edges, each
    the form's least along the edge clamped to it.

    Args:
        low: (..., 3) the least change of each angle [rad].
        high: (..., 3) the largest, ``high >= low``.
        kappa: (...) the coupling of the first and third angles, in [-1, 1].

    Returns:
        (...) [rad^2].
    """
    middle = np.clip(0.0, low[..., 1], high[..., 1])
    l1, h1, l3, h3 = low[..., 0], high[..., 0], low[..., 2], high[..., 2]
    best = np.full(np.shape(l1), np.inf)
    for d1 in (l1, h1):  # the edges d1 = const, d3 at its best along them
        d3 = np.clip(-kappa * d1, l3, h3)
        best = np.minimum(best, d1 * d1 + d3 * d3 + 2.0 * kappa * d1 * d3)
    for d3 in (l3, h3):
        d1 = np.clip(-kappa * d3, l1, h1)
        best = np.minimum(best, d1 * d1 + d3 * d3 + 2.0 * kappa * d1 * d3)
    inside = (l1 <= 0.0) & (h1 >= 0.0) & (l3 <= 0.0) & (h3 >= 0.0)
    return middle * middle + np.where(inside, 0.0, best)
