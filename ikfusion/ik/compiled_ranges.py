"""The ranges of motion linearised inside the compiled step (CasADi).

The twin of :meth:`.limits.JointRangeLimit.linearise`. Each joint's anatomical angles are
measured on the Euler triple closest to its range (as
:func:`ikfusion.model.angle_continuity.nearest_to_ranges`: the first and third angles wrapped
within half a turn of the middle of their range, the branch with the smaller squared distance
outside the range kept; on the other branch the middle angle's rate changes sign). Outputs, for
``j`` ball joints: the rows ``G`` (3j, nv) of the angles' rates per unit tangent step and the
room to the limits ``upper - a`` and ``a - lower`` (3j) [rad], so that the linearised limits
read ``G dq <= upper - a`` and ``-G dq <= a - lower``.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

_TURN = 2.0 * np.pi


def _wrap_near(a: ca.SX, centre: ca.SX) -> ca.SX:
    """``a`` shifted by whole turns to within half a turn of ``centre`` [rad]."""
    return a + _TURN * ca.floor((centre - a) / _TURN + 0.5)


def _outside(a: ca.SX, lower: ca.SX, upper: ca.SX) -> ca.SX:
    """Squared distance [rad^2] of the triple ``a`` outside its range."""
    beyond = ca.fmax(ca.fmax(lower - a, a - upper), 0.0)
    return ca.sumsqr(beyond)


def range_rows(angles: Sequence[ca.SX], rates: Sequence[ca.SX], idx_v: Sequence[int],
               lower: ca.SX, upper: ca.SX, nv: int) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(G (3j, nv), room_up (3j), room_down (3j))`` of the linearised ranges of motion.

    Args:
        angles: Per joint, its principal anatomical angles (3) [rad].
        rates: Per joint, ``E^-1`` (3, 3): angle rates per unit tangent step of the joint.
        idx_v: Per joint, its first tangent column.
        lower: Lower limits (3j) [rad], joint by joint.
        upper: Upper limits (3j) [rad].
        nv: Tangent size.
    """
    G = ca.SX(3 * len(angles), nv)
    up, down = [], []
    other_signs = ca.DM([1.0, -1.0, 1.0])
    for n, (a, E_inv, col) in enumerate(zip(angles, rates, idx_v)):
        lo, hi = lower[3 * n:3 * n + 3], upper[3 * n:3 * n + 3]
        centre = 0.5 * (lo + hi)
        same = _wrap_near(a, centre)
        other = _wrap_near(a * other_signs + np.pi, centre)
        flipped = _outside(other, lo, hi) < _outside(same, lo, hi)
        chosen = ca.if_else(flipped, other, same)
        middle_sign = ca.if_else(flipped, -1.0, 1.0)
        G[3 * n, col:col + 3] = E_inv[0, :]
        G[3 * n + 1, col:col + 3] = middle_sign * E_inv[1, :]
        G[3 * n + 2, col:col + 3] = E_inv[2, :]
        up.append(hi - chosen)
        down.append(chosen - lo)
    empty = ca.SX(0, 1)
    return G, ca.vertcat(*up) if up else empty, ca.vertcat(*down) if down else empty
