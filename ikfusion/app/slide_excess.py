"""How much further a solve's contact points slid than the truth's (``evaluate``'s excess).

Per contact phase of the truth and contact point, the largest horizontal slide of the solved
point from where it was when the phase began, minus the same of the true point, at least 0
(:func:`excess_slides`) [m]: the skating a solve adds, free of the truth's loose phases.

A truth read from motion capture onto our body is not always a body on a floor: its limb
points are lifted onto it (within the floor fit's scatter,
:data:`ikfusion.mocap.from_bvh.FLOOR_OUTLIER`; a toe of amp-walk 2.5 cm deep), but the trunk
points where a lying body rests (:data:`~ikfusion.model.layout.TRUNK_CONTACT_SITES`: our model's
guess of the back's surface, not the captured body's) are not, and may lie centimetres deep
(dm-getup-faceup: a shoulder blade 7 cm under the floor while it slides 5 cm). A solve holds
such a point on the floor, where it stays; the truth moves it through the floor, and the whole
solved body falls behind the true one by that motion. No solve on a floor can follow it, so
:func:`sunk_steps` finds those steps and ``excess_slides(..., skip=)`` leaves the solved points'
motion relative to the true ones out over them: the points move there as the true ones do, and
every other step counts as before (a held point that moves, a release, a hand-over, a point the
solver let go that slides).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model.layout import TRUNK_CONTACT_SITES

#: A true trunk point deeper than this under the floor [m] is not on it: the truth's floor fit
#: leaves its points up to this deep (:data:`ikfusion.mocap.from_bvh.FLOOR_OUTLIER`).
SUNK_DEPTH = 0.02


def sunk_steps(held: np.ndarray, z_true: np.ndarray, names: Sequence[str],
               depth: float = SUNK_DEPTH) -> np.ndarray:
    """(N - 1,) the steps ``k -> k + 1`` in which the solve holds a trunk point sunk in the truth.

    Args:
        held: (N, h) the points the solver holds planted in each frame.
        z_true: (N, h) the same points' true heights [m] (floor at z = 0).
        names: (h,) their names; only :data:`~ikfusion.model.layout.TRUNK_CONTACT_SITES` count
            (the truth lifts the others onto the floor).
        depth: A true point deeper than this under the floor is sunk [m].

    Returns:
        True where the solver holds, at the step's end, a trunk point the truth has more than
        ``depth`` under the floor.
    """
    trunk = np.array([n in TRUNK_CONTACT_SITES for n in names], dtype=bool)
    if not trunk.any() or len(held) < 2:
        return np.zeros(max(len(held) - 1, 0), dtype=bool)
    return np.asarray(np.any((held[1:] & (z_true[1:] < -depth))[:, trunk], axis=1))


def excess_slides(P_est: np.ndarray, P_true: np.ndarray, contacts: np.ndarray,
                  skip: np.ndarray | None = None) -> list[float]:
    """Per contact phase of the truth, how much further the solved point slid [m].

    Args:
        P_est: (N, k, 3) the solved points [m].
        P_true: (N, k, 3) the true points [m].
        contacts: (N, k) the truth's contact phases.
        skip: (N - 1,) steps over which the solved points move as the true ones do
            (:func:`sunk_steps`; None: none).

    Returns:
        ``max(0, slide_solved - slide_true)`` per phase (slides: the largest horizontal
        distance from where the point was when the phase began), points in column order.
    """
    est = P_est[..., :2]
    if skip is not None and bool(np.any(skip)):
        relative = np.diff(est - P_true[..., :2], axis=0) * skip[:, None, None]
        est = est - np.concatenate([np.zeros_like(est[:1]), np.cumsum(relative, axis=0)])
    out = []
    for i in range(contacts.shape[1]):
        edges = np.diff(np.r_[0, np.asarray(contacts[:, i], dtype=np.int8), 0])
        for start, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1),
                              strict=True):
            solved = np.linalg.norm(est[start:end, i] - est[start, i], axis=1).max()
            true = np.linalg.norm(P_true[start:end, i, :2] - P_true[start, i, :2], axis=1).max()
            out.append(max(0.0, float(solved - true)))
    return out
