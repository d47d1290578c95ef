"""The step's QP handed to DAQP as a least-distance problem, on our own factorisation of H.

    minimise    1/2 x^T H x + c^T x
    subject to  lower <= C x <= upper     (bounds, inequality rows, equality rows)

DAQP solves its dual in the space of the constraint rows, after a set-up that factorises ``H``
and inverts the factor with its own loops at every call: on the real walk's steps (72
variables, 16 rows, two active-set iterations) that set-up took 125 of the 136 us of a call,
its iterations 3 us (issue #20). With ``H = L L^T`` (LAPACK) and ``u = L^T x + L^-1 c`` the
same problem is

    minimise    1/2 |u|^2
    subject to  lower + M v <= M u <= upper + M v,   M = C L^-T,  v = L^-1 c,

whose Hessian is the identity, which DAQP detects and sets up in ``O(m n)``; then
``x = L^-T (u - v)``. DAQP runs the same iterations on the same scaled rows (it scales each row
of ``M`` to unit length either way) with the same tolerances in the rows' own units, so it
finds the same active set and the same step to rounding. The triangular solves are LAPACK's,
one for all the rows.

A step's packed QP without bounds (the solver's, :class:`.qp.QpBuffer`) takes ``L = U D^1/2``
from the native tree factor ``H = U D U^T`` instead (:mod:`.tree_solve`: no fill, a few
thousand operations where LAPACK's Cholesky and solves took about 35 of a call's 62 us on the
real walk). Any two factors of ``H`` differ by an orthogonal matrix ``Q`` (``M`` becomes
``M Q``, ``u`` becomes ``Q^T u``), which keeps the rows' lengths and angles and ``M v``: DAQP
takes the same decisions and returns the same step to rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg.lapack import dpotrf, dtrtrs

from .fast_math import any_true, sum_of

if TYPE_CHECKING:
    from .tree_solve import TreeClosedForm

#: DAQP's infinity: a bound beyond it is absent.
INFINITE = 1e30
#: DAQP's sense of an equality row.
EQUALITY = 5


@dataclass
class LeastDistanceCounts:
    """How the least-distance form fared, for tests and benchmarks (never silent).

    Attributes:
        solved: Problems solved in the least-distance form.
        fallbacks: Problems it could not solve (``H`` not numerically positive definite, or
            DAQP's exit flag not optimal), which the caller then hands to DAQP as they are.
    """

    solved: int = 0
    fallbacks: int = 0


#: Counts over the process's lifetime.
COUNTS = LeastDistanceCounts()


def row_bounds(n_box: int, lb: np.ndarray | None, ub: np.ndarray | None, h: np.ndarray | None,
               b: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """DAQP's ``(upper, lower)`` of the rows: ``n_box`` bounds (0 or n), then ``h``, then ``b``.

    An absent bound is ``+-INFINITE``; equality rows have ``lower = upper = b``.
    """
    n_in = 0 if h is None else len(h)
    end_in = n_box + n_in
    upper = np.empty(end_in + (0 if b is None else len(b)))
    lower = np.empty_like(upper)
    if n_box:
        upper[:n_box] = INFINITE if ub is None else ub
        lower[:n_box] = -INFINITE if lb is None else lb
    if h is not None and n_in:
        upper[n_box:end_in] = h
        lower[n_box:end_in] = -INFINITE
    if b is not None and len(b):
        upper[end_in:] = b
        lower[end_in:] = b
    return upper, lower


def least_distance_daqp(daqp: Any, max_iterations: int, H: np.ndarray, c: np.ndarray,
                        G: np.ndarray | None, h: np.ndarray | None, A: np.ndarray | None,
                        b: np.ndarray | None, lb: np.ndarray | None,
                        ub: np.ndarray | None,
                        native: tuple[TreeClosedForm, np.ndarray] | None = None
                        ) -> tuple[np.ndarray, bool] | None:
    """The QP's step by DAQP in the least-distance form (module docstring).

    Args:
        daqp: The imported ``daqp`` module.
        max_iterations: DAQP's iteration limit.
        H: (n, n) Hessian, symmetric positive definite (not changed); :func:`identity`
            itself is not factored.
        c: (n,) gradient at ``x = 0``.
        G: (m_in, n) inequality rows ``G x <= h``, or None.
        h: (m_in,) their bounds, or None.
        A: (m_eq, n) equality rows ``A x = b``, or None.
        b: (m_eq,) their values, or None.
        lb: (n,) lower bounds on ``x``, or None.
        ub: (n,) upper bounds on ``x``, or None.
        native: The native tree factor and the packed problem these arrays are views of
            (:meth:`.tree_solve.TreeClosedForm.least_distance_rows`, used without bounds), or
            None: LAPACK's factor.

    Returns:
        The step (n,) and whether an inequality row or a bound binds at it (a non-zero
        multiplier); None when ``H`` is not numerically positive definite or DAQP does not
        find the optimum (the caller then calls DAQP on the problem as it is).
    """
    n = len(c)
    shared_identity = H is identity(n)  # L = I: no factorisation, no triangular solves
    if native is not None and not shared_identity and lb is None and ub is None:
        n_in, n_eq = (0 if h is None else len(h)), (0 if b is None else len(b))
        rows = native[0].least_distance_rows(native[1], n_in, n_eq)
        if rows is not None:  # else H is off the tree's pattern (or not positive definite)
            return _tree_least_distance(daqp, max_iterations, native[0], rows, n_in)
    L, info = (H, 0) if shared_identity else dpotrf(H, lower=1, clean=0)  # lower triangle read
    if info != 0:
        return None
    n_box = n if lb is not None or ub is not None else 0
    n_in = 0 if h is None or G is None else len(h)
    end_in = n_box + n_in
    rhs = np.empty((n, 1 + end_in + (0 if b is None else len(b))), order="F")
    rhs[:, 0] = c
    if n_box:
        rhs[:, 1:1 + n_box] = identity(n)
    if n_in:
        rhs[:, 1 + n_box:1 + end_in] = G.T  # type: ignore[union-attr]
    if A is not None and b is not None and len(b):
        rhs[:, 1 + end_in:] = A.T
    Y, info = (rhs, 0) if shared_identity else dtrtrs(L, rhs, lower=1)  # L^-1 [c, C^T]
    if info != 0:
        return None
    v = Y[:, 0]
    M = Y[:, 1:].T  # (m, n) C-contiguous: the rows in u
    upper, lower = row_bounds(n_box, lb, ub, h, b)
    Mv = M @ v
    upper += Mv  # an absent bound stays at +-INFINITE (|M v| is far below its spacing)
    lower += Mv
    solved = _distance_daqp(daqp, max_iterations, M, upper, lower, end_in)
    if solved is None:
        return None
    u, binding = solved
    x, info = (np.subtract(u, v), 0) if shared_identity else \
        dtrtrs(L, np.subtract(u, v), lower=1, trans=1)
    if info != 0 or not math.isfinite(sum_of(x)):
        return None
    return x, binding


def _tree_least_distance(daqp: Any, max_iterations: int, tree: TreeClosedForm,
                         rows: tuple[np.ndarray, np.ndarray, np.ndarray],
                         n_in: int) -> tuple[np.ndarray, bool] | None:
    """:func:`least_distance_daqp` on the native tree factor's rows ``(M, upper, lower)``."""
    solved = _distance_daqp(daqp, max_iterations, *rows, n_in)
    x = None if solved is None else tree.least_distance_step(solved[0])
    return None if x is None or solved is None else (x.copy(), solved[1])


def _distance_daqp(daqp: Any, max_iterations: int, M: np.ndarray, upper: np.ndarray,
                   lower: np.ndarray, end_in: int) -> tuple[np.ndarray, bool] | None:
    """DAQP on ``min 1/2 |u|^2, lower <= M u <= upper`` (rows from ``end_in`` on equalities).

    Returns ``u`` and whether a row before ``end_in`` binds (a non-zero multiplier), or None
    when DAQP does not find the optimum.
    """
    n = M.shape[1]
    u, _, exitflag, result = daqp.solve(identity(n), _zeros(n), M, upper, lower,
                                        senses(len(upper), end_in), iter_limit=max_iterations)
    if exitflag <= 0:
        return None
    return u, any_true(result["lam"][:end_in])


@cache
def identity(n: int) -> np.ndarray:
    """The shared (n, n) identity: the least-distance problem's Hessian (never written).

    Writable only because DAQP's interface takes writable arrays (it reads this one). A QP
    whose ``H`` is this very array (the projection's, :mod:`.projection`) skips the
    factorisation of ``H`` and the solves with its factor, in :func:`least_distance_daqp` and
    :func:`.equality_qp.equality_optimum`: they would return their right-hand sides' numbers
    (up to the sign of a zero).
    """
    return np.eye(n)


@cache
def senses(m: int, end_in: int) -> np.ndarray:
    """DAQP's senses of ``m`` rows: inequalities (0) before ``end_in``, equalities after.

    Shared, made once per shape (an array built at every call cost 1.5 us); never written:
    DAQP copies the senses into its own workspace (it changes a caller's senses only when
    given a warm start, which is never asked for here). Writable only because its interface
    takes writable arrays.
    """
    sense = np.zeros(m, dtype=np.intc)
    sense[end_in:] = EQUALITY
    return sense


@cache
def _zeros(n: int) -> np.ndarray:
    """(n,) zeros: its linear term."""
    return np.zeros(n)
