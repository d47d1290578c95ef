"""The QP of a step solved in closed form when none of its inequalities is active.

Most steps of a frame touch no limit: no range of motion, no floor row and no velocity bound
binds, and the optimum of the step's strictly convex QP is the minimiser of its objective on
the equality rows (the planted contact points) alone. That minimiser comes from two Cholesky
factorisations (of ``H`` and of the small Schur complement ``A H^-1 A^T``) in far less time
than an active-set solve. When it satisfies every inequality and bound it is the QP's unique
optimum (the KKT conditions hold with zero inequality multipliers). When it crosses a few
inequality rows (a limit or the floor binds), holding exactly those rows usually gives the
optimum, from the same factorisation of ``H``, checked by the KKT conditions
(:func:`closed_form_optimum`); otherwise the caller solves the full QP.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dpotrf, dpotrs


def equality_optimum(H: np.ndarray, c: np.ndarray, A: np.ndarray | None,
                     b: np.ndarray | None) -> np.ndarray | None:
    """``argmin 1/2 x^T H x + c^T x`` subject to ``A x = b`` (inequalities ignored).

    Args:
        H: (n, n) the objective's Hessian, symmetric positive definite.
        c: (n,) the objective's gradient at ``x = 0``.
        A: (m, n) equality rows, or None.
        b: (m,) their right-hand sides, or None.

    Returns:
        The minimiser (n,), or None when ``H`` or ``A H^-1 A^T`` is not numerically positive
        definite (e.g. dependent equality rows): the caller's QP solver decides then.
    """
    L, info = dpotrf(H, lower=1, clean=0)
    if info != 0:
        return None
    found = _minimiser(L, c, A, b)
    return None if found is None else found[0]


def closed_form_optimum(H: np.ndarray, c: np.ndarray, G: np.ndarray | None,
                        h: np.ndarray | None, A: np.ndarray | None, b: np.ndarray | None,
                        lb: np.ndarray | None, ub: np.ndarray | None) -> np.ndarray | None:
    """The QP's optimum in closed form when no inequality binds, or only those it crosses.

    First the minimiser on the equality rows (:func:`equality_optimum`). When it crosses some
    inequality rows ``G x <= h`` (a range of motion, the floor), those rows are held as
    equalities too and the minimiser taken again from the same factorisation of ``H``; it is
    the QP's unique optimum when it satisfies every other row and bound and the multipliers of
    the held rows are nonnegative (the KKT conditions). Otherwise None: the caller's QP solver
    decides (bounds crossed, rows that stop binding once others bind, dependent rows).

    Args:
        H: (n, n) the objective's Hessian ``1/2 x^T H x + c^T x``, positive definite.
        c: (n,) its gradient at ``x = 0``.
        G: (k, n) inequality rows ``G x <= h``, or None.
        h: (k,) their right-hand sides, or None.
        A: (m, n) equality rows ``A x = b``, or None.
        b: (m,) their right-hand sides, or None.
        lb: (n,) lower bounds on ``x``, or None.
        ub: (n,) upper bounds on ``x``, or None.
    """
    L, info = dpotrf(H, lower=1, clean=0)
    if info != 0:
        return None
    found = _minimiser(L, c, A, b)
    if found is None:
        return None
    x = found[0]
    if satisfies(x, G, h, lb, ub):
        return x
    if G is None or h is None or not _within(x, lb, ub):
        return None
    held = G @ x > h
    m = 0 if A is None or b is None else len(b)
    rows = G[held] if not m else np.vstack([A, G[held]])
    targets = h[held] if not m else np.concatenate([b, h[held]])
    found = _minimiser(L, c, rows, targets)
    if found is None or found[1][m:].min() < 0.0:
        return None
    x = found[0]
    free = ~held
    return x if satisfies(x, G[free], h[free], lb, ub) else None


def _minimiser(L: np.ndarray, c: np.ndarray, A: np.ndarray | None,
               b: np.ndarray | None) -> tuple[np.ndarray, np.ndarray] | None:
    """The minimiser on ``A x = b`` from the Cholesky factor ``L`` of ``H``, and multipliers.

    The multipliers ``y`` (m,) are those of ``H x + c + A^T y = 0``. None when ``A H^-1 A^T``
    is not numerically positive definite or the result is not finite.
    """
    rows = A if A is not None and b is not None and len(b) else None
    m = 0 if rows is None else len(rows)
    # one solve for every right-hand side: -c, then the equality rows (H^-1 A^T)
    rhs = np.empty((len(c), 1 + m), order="F")
    rhs[:, 0] = -c
    if rows is not None:
        rhs[:, 1:] = rows.T
    X, info = dpotrs(L, rhs, lower=1, overwrite_b=1)
    if info != 0:
        return None
    x = X[:, 0]
    multipliers = np.zeros(0)
    if rows is not None and b is not None:
        Y = X[:, 1:]
        solved = independent_solve(rows @ Y, rows @ x - b)
        if solved is None:
            return None
        multipliers = solved
        x = x - Y @ multipliers
    return (np.asarray(x), multipliers) if np.isfinite(x.sum()) else None


def independent_solve(S: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """``S^-1 r`` for a Gram matrix ``S = A W A^T`` (m, m) of rows ``A`` and ``r`` (m,).

    None when the rows are (nearly) dependent: the smallest squared Cholesky pivot of ``S``
    is below ``1e-12`` of its largest diagonal entry (a condition number of about 1e6 of the
    rows), where the solution loses its accuracy.
    """
    factor, info = dpotrf(S, lower=1, clean=0)
    if info != 0 or factor.diagonal().min() ** 2 < _DEPENDENT_ROWS * S.diagonal().max():
        return None
    y, info = dpotrs(factor, r, lower=1)
    return np.asarray(y) if info == 0 else None


def satisfies(x: np.ndarray, G: np.ndarray | None, h: np.ndarray | None,
              lb: np.ndarray | None, ub: np.ndarray | None) -> bool:
    """Whether ``x`` satisfies ``G x <= h`` and ``lb <= x <= ub`` (exactly, no tolerance)."""
    if G is not None and h is not None and len(h) and not bool(np.all(G @ x <= h)):
        return False
    return _within(x, lb, ub)


def _within(x: np.ndarray, lb: np.ndarray | None, ub: np.ndarray | None) -> bool:
    """Whether ``lb <= x <= ub`` (exactly)."""
    if lb is not None and not bool(np.all(x >= lb)):
        return False
    return ub is None or bool(np.all(x <= ub))


#: Smallest squared Cholesky pivot of a Gram matrix relative to its largest diagonal entry
#: before its rows count as dependent (:func:`independent_solve`).
_DEPENDENT_ROWS = 1e-12
