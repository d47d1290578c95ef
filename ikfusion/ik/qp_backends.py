"""The QP backends beside DAQP: whether one is installed, and its options (:mod:`.qp`).

qpsolvers is imported on first use only: DAQP, the default, is called directly.
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .qp import QpSettings


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
