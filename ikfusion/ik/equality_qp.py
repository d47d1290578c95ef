"""The QP of a step solved in closed form when none of its inequalities is active.

Most steps of a frame touch no limit: no range of motion, no floor row and no velocity bound
binds, and the optimum of the step's strictly convex QP is the minimiser of its objective on
the equality rows (the planted contact points) alone. That minimiser comes from two Cholesky
factorisations (of ``H`` and of the small Schur complement ``A H^-1 A^T``) in far less time
than an active-set solve. When it satisfies every inequality and bound it is the QP's unique
optimum (the KKT conditions hold with zero inequality multipliers); otherwise the caller solves
the full QP.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dposv

from .fast_math import min_of, sum_of
from .least_distance import identity


@dataclass
class ClosedFormHint:
    """Whether the next step skips its closed-form try and goes to DAQP at once (issue #20).

    A limit that binds in one step mostly binds in the next one too: on ``opensense_walk``
    (8 sensors) the closed-form try failed in 94 % of the steps after a step where it failed,
    in 2 % after one where it held; a failed try only costs time. :func:`.qp.solve_qp` sets
    :attr:`skip` after every DAQP solve: True when an inequality or a bound binds at its
    optimum (a non-zero multiplier), where the closed form would have failed. The answer is the
    QP's unique optimum either way (DAQP's to its tolerance, the closed form's to rounding).

    Attributes:
        skip: Go to DAQP without the closed-form try.
    """

    skip: bool = False


def equality_optimum(H: np.ndarray, c: np.ndarray, A: np.ndarray | None,
                     b: np.ndarray | None) -> np.ndarray | None:
    """``argmin 1/2 x^T H x + c^T x`` subject to ``A x = b`` (inequalities ignored).

    Args:
        H: (n, n) the objective's Hessian, symmetric positive definite
            (:func:`.least_distance.identity` itself: not factored).
        c: (n,) the objective's gradient at ``x = 0``.
        A: (m, n) equality rows, or None.
        b: (m,) their right-hand sides, or None.

    Returns:
        The minimiser (n,), or None when ``H`` or ``A H^-1 A^T`` is not numerically positive
        definite (e.g. dependent equality rows): the caller's QP solver decides then.
    """
    # dposv: LAPACK's dpotrf then dpotrs (the same numbers) in one call
    rows = A if A is not None and b is not None and len(b) else None
    shared_identity = H is identity(len(c))  # H^-1 = I: nothing to solve
    if rows is None:  # no equality rows (no planted point): one solve, nothing to stack
        _, x, info = (None, np.negative(c), 0) if shared_identity else \
            dposv(H, np.negative(c), lower=1, overwrite_b=1)
        return x if info == 0 and math.isfinite(sum_of(x)) else None
    m = len(rows)
    # one solve for every right-hand side: -c, then the equality rows (H^-1 A^T)
    rhs = np.empty((len(c), 1 + m), order="F")
    rhs[:, 0] = -c
    rhs[:, 1:] = rows.T
    _, X, info = (None, rhs, 0) if shared_identity else dposv(H, rhs, lower=1, overwrite_b=1)
    if info != 0 or b is None:
        return None
    Y = X[:, 1:]
    multipliers = independent_solve(rows @ Y, rows @ X[:, 0] - b)
    if multipliers is None:
        return None
    x = X[:, 0] - Y @ multipliers
    return np.asarray(x) if np.isfinite(x.sum()) else None


def independent_solve(S: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """``S^-1 r`` for a Gram matrix ``S = A W A^T`` (m, m) of rows ``A`` and ``r`` (m,).

    None when the rows are (nearly) dependent: the smallest squared Cholesky pivot of ``S``
    is below ``1e-12`` of its largest diagonal entry (a condition number of about 1e6 of the
    rows), where the solution loses its accuracy.
    """
    # dposv: dpotrf then dpotrs (the same numbers) in one call; its factor is checked after
    # (the solve is wasted only on dependent rows, which are rare)
    factor, y, info = dposv(S, r, lower=1)
    if info != 0 or min_of(factor.diagonal()) ** 2 < \
            DEPENDENT_ROWS * np.maximum.reduce(S.diagonal(), axis=None):
        return None
    return y


def satisfies(x: np.ndarray, G: np.ndarray | None, h: np.ndarray | None,
              lb: np.ndarray | None, ub: np.ndarray | None) -> bool:
    """Whether ``x`` satisfies ``G x <= h`` and ``lb <= x <= ub`` (exactly, no tolerance)."""
    # the arrays' own all(): the same test without NumPy's per-call dispatch
    if G is not None and h is not None and len(h) and not (G @ x <= h).all():
        return False
    if lb is not None and not (x >= lb).all():
        return False
    return ub is None or bool((x <= ub).all())


#: Smallest squared Cholesky pivot of a Gram matrix relative to its largest diagonal entry
#: before its rows count as dependent (:func:`independent_solve`).
DEPENDENT_ROWS = 1e-12
