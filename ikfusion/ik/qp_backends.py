"""The QP backends: DAQP called directly, the others through qpsolvers (:mod:`.qp`).

qpsolvers is imported on first use only: DAQP, the default, is called directly.
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING, Any

import numpy as np

from .least_distance import COUNTS, least_distance_daqp, row_bounds, senses

if TYPE_CHECKING:
    from .qp import QpSettings
    from .tree_solve import TreeClosedForm


def solver_options(backend: str, settings: QpSettings) -> dict[str, Any]:
    """The keyword options of ``backend`` in qpsolvers from the QP settings."""
    if backend == "osqp":
        return {"eps_abs": settings.osqp_tolerance, "eps_rel": settings.osqp_tolerance,
                "polish": True, "max_iter": settings.osqp_max_iterations, "verbose": False}
    if backend == "proxqp":
        return {"max_iter": settings.max_iterations, "max_iter_in": settings.max_iterations}
    return {}


@cache
def installed(backend: str) -> bool:
    """Whether ``backend`` can be called (DAQP checked without importing qpsolvers)."""
    if backend == "daqp":
        try:
            import daqp  # noqa: F401 - imported to see that it is there
        except ImportError:
            return False
        return True
    return backend in qpsolvers_module().available_solvers


def qpsolvers_module() -> Any:
    """The qpsolvers module, imported on first use (about 0.3 s; DAQP is called directly)."""
    import qpsolvers

    return qpsolvers


def call_daqp(max_iterations: int, H: np.ndarray, c: np.ndarray, G: np.ndarray | None,
              h: np.ndarray | None, A: np.ndarray | None, b: np.ndarray | None,
              lb: np.ndarray | None, ub: np.ndarray | None,
              native: tuple[TreeClosedForm, np.ndarray] | None = None
              ) -> tuple[np.ndarray | None, bool]:
    """DAQP called directly (the same problem qpsolvers would pass, without its checks).

    The problem goes to DAQP in the least-distance form on our own factorisation of ``H``
    (:mod:`.least_distance`, the same step in a fraction of DAQP's set-up; ``native``: the
    tree factor and the packed problem, when the arrays are its views), and as it is when
    that form fails (counted in :data:`.least_distance.COUNTS`).

    Returns:
        The step (None when DAQP fails) and whether an inequality row or a bound binds at it
        (a non-zero multiplier; False when DAQP fails).
    """
    import daqp  # the default backend; imported here so that the others work without it

    solved = least_distance_daqp(daqp, max_iterations, H, c, G, h, A, b, lb, ub,
                                 native=native)
    if solved is not None:
        COUNTS.solved += 1
        return solved
    COUNTS.fallbacks += 1
    return daqp_as_given(daqp, max_iterations, H, c, G, h, A, b, lb, ub)


def daqp_as_given(daqp: Any, max_iterations: int, H: np.ndarray, c: np.ndarray,
                  G: np.ndarray | None, h: np.ndarray | None, A: np.ndarray | None,
                  b: np.ndarray | None, lb: np.ndarray | None,
                  ub: np.ndarray | None) -> tuple[np.ndarray | None, bool]:
    """DAQP on the problem as it is (:func:`call_daqp`'s fall-back; ``daqp``: the module).

    DAQP takes simple bounds as the first rows of ``blower <= (dq, A_rows dq) <= bupper`` and
    marks equality rows with sense 5.
    """
    nv = len(c)
    n_box = nv if lb is not None or ub is not None else 0
    upper, lower = row_bounds(n_box, lb, ub, h, b)
    end_in = n_box + (0 if h is None else len(h))
    rows = [m for m in (G, A) if m is not None]
    A_all = np.vstack(rows) if rows else np.zeros((0, nv))  # a copy: DAQP may scale its rows
    x, _, exitflag, info = daqp.solve(H, c, A_all, upper, lower, senses(len(upper), end_in),
                                      iter_limit=max_iterations)
    if exitflag <= 0 or not np.isfinite(x).all():
        return None, False
    return np.asarray(x), bool(np.count_nonzero(info["lam"][:end_in]))
