"""ikfusion: drift-free full-body human motion from body-worn IMUs and UWB.

The public names are re-exported here; see SPEC section 7 for the contract. They are imported
on first use (PEP 562), so ``import ikfusion`` and the command line start without loading
Pinocchio and NumPy; Ctrl-C while those load is then handled by :func:`ikfusion.cli.main`.
"""

import importlib as _importlib
import importlib.util as _importlib_util
import os as _os
from typing import TYPE_CHECKING, Any

# The solver's QPs are small (72 variables): a multithreaded BLAS only adds overhead (3-5x
# slower measured here). Default to one thread unless the user chose otherwise; this must run
# before NumPy is imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

from .errors import ConfigError, IkfusionError, InputError, NameNotFound, SolverError  # noqa: E402
from .native.typed_modules import enable as _enable_typed_modules  # noqa: E402

_enable_typed_modules()  # the solver's modules compiled by mypyc, when built (opt-in)

if TYPE_CHECKING:
    from .ik import Frame, Motion, Pose, Solver, SolverSettings
    from .model import Body, HumanModel

#: Public names imported on first use, and the module that defines each.
_LAZY = {
    "Frame": ".ik", "Motion": ".ik", "Pose": ".ik", "Solver": ".ik", "SolverSettings": ".ik",
    "Body": ".model", "HumanModel": ".model",
}


def __getattr__(name: str) -> Any:
    """Import a public name (or a subpackage such as ``ikfusion.io``) on first use."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(_LAZY[name], __name__), name)
    elif not name.startswith("_") and _importlib_util.find_spec(f"{__name__}.{name}"):
        value = _importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


__all__ = [
    "Body",
    "Frame",
    "HumanModel",
    "Motion",
    "Pose",
    "Solver",
    "SolverSettings",
    "ConfigError",
    "IkfusionError",
    "InputError",
    "NameNotFound",
    "SolverError",
]

__version__ = "0.1.0"
