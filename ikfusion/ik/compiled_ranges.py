"""The ranges of motion linearised inside the compiled step (CasADi).

The twin of :meth:`.limits.JointRangeLimit.linearise`. Each joint's anatomical angles are
measured on the Euler triple closest to its range (as
:func:`ikfusion.model.angle_continuity.nearest_to_ranges`: the first and third angles wrapped
within half a turn of the middle of their range, the branch that the smaller turn of the joint
brings into its range kept (:func:`~ikfusion.model.angle_continuity.turn_into_range`); on the
other branch the middle angle's rate changes sign). Outputs, for
``j`` ball joints: the rows ``G`` (3j, nv) of the angles' rates per unit tangent step and the
room to the limits ``upper - a`` and ``a - lower`` (3j) [rad], so that the linearised limits
read ``G dq <= upper - a`` and ``-G dq <= a - lower``. An angle's rates at gimbal lock (not
finite there) are 0, as :func:`.limits.joint_range.finite_rates` makes them.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

_TURN = 2.0 * np.pi
_STEEPEST = 1e8  # an angle's rate [rad/rad] beyond this (or not finite): a joint at the lock


def _wrap_near(a: ca.SX, centre: ca.SX) -> ca.SX:
    """``a`` shifted by whole turns to within half a turn of ``centre`` [rad]."""
    return a + _TURN * ca.floor((centre - a) / _TURN + 0.5)


def _turn_into_range(low: ca.SX, high: ca.SX, kappa: ca.SX) -> ca.SX:
    """Squared turn [rad^2] that brings a triple into its range.

    The twin of :func:`ikfusion.model.angle_continuity.turn_into_range`, ``low`` and ``high``
    (3,) for one joint.
    """
    middle = ca.fmin(ca.fmax(0.0, low[1]), high[1])
    l1, h1, l3, h3 = low[0], high[0], low[2], high[2]

    def form(d1: ca.SX, d3: ca.SX) -> ca.SX:
        return d1 * d1 + d3 * d3 + 2.0 * kappa * d1 * d3

    edges = [form(d1, ca.fmin(ca.fmax(-kappa * d1, l3), h3)) for d1 in (l1, h1)]
    edges += [form(ca.fmin(ca.fmax(-kappa * d3, l1), h1), d3) for d3 in (l3, h3)]
    best = ca.fmin(ca.fmin(edges[0], edges[1]), ca.fmin(edges[2], edges[3]))
    inside = ca.logic_and(ca.logic_and(l1 <= 0.0, h1 >= 0.0), ca.logic_and(l3 <= 0.0, h3 >= 0.0))
    return middle * middle + ca.if_else(inside, 0.0, best)


def range_block(a: ca.SX, E_inv: ca.SX, lo: ca.SX, hi: ca.SX, coupling: float | ca.SX
                ) -> tuple[ca.SX, ca.SX, ca.SX]:
    """One joint's ``(G (3, 3), room_up (3), room_down (3))`` on its three tangent columns.

    Args:
        a: Its principal anatomical angles (3) [rad].
        E_inv: ``E^-1`` (3, 3): angle rates per unit tangent step of the joint.
        lo: Lower limits (3) [rad].
        hi: Upper limits (3) [rad].
        coupling: Its :attr:`~ikfusion.model.joints.JointSpec.axis_coupling`.
    """
    centre = 0.5 * (lo + hi)
    same = _wrap_near(a, centre)
    other = _wrap_near(a * ca.DM([1.0, -1.0, 1.0]) + np.pi, centre)
    kappa = coupling * ca.sin(a[1])
    flipped = (_turn_into_range(lo - other, hi - other, kappa)
               < _turn_into_range(lo - same, hi - same, kappa))
    chosen = ca.if_else(flipped, other, same)
    signs: tuple[ca.SX, ...] = (ca.SX(1.0), ca.if_else(flipped, -1.0, 1.0), ca.SX(1.0))
    G = ca.SX(3, 3)
    for m, sign in enumerate(signs):
        row = E_inv[m, :]
        tame = ca.logic_and(ca.logic_and(ca.fabs(row[0]) < _STEEPEST,  # NaN compares false
                                         ca.fabs(row[1]) < _STEEPEST),
                            ca.fabs(row[2]) < _STEEPEST)
        G[m, :] = ca.if_else(tame, sign * row, ca.DM.zeros(1, 3))
    return G, hi - chosen, chosen - lo


def range_matrix(blocks: Sequence[ca.SX], idx_v: Sequence[int], nv: int) -> ca.SX:
    """``G`` (3j, nv): each joint's block (3, 3) on its rows and its columns from ``idx_v``."""
    G = ca.SX(3 * len(blocks), nv)
    for n, (block, col) in enumerate(zip(blocks, idx_v)):
        G[3 * n:3 * n + 3, col:col + 3] = block
    return G

