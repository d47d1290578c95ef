"""ikfusion: drift-free full-body human motion from body-worn IMUs and UWB.

The public names are re-exported here; see SPEC section 7 for the contract.
"""

import os as _os

# The solver's QPs are small (72 variables): a multithreaded BLAS only adds overhead (3-5x
# slower measured here). Default to one thread unless the user chose otherwise; this must run
# before NumPy is imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

from .errors import ConfigError, IkfusionError, InputError, NameNotFound, SolverError  # noqa: E402
from .ik import Frame, Motion, Pose, Solver, SolverSettings  # noqa: E402
from .model import Body, HumanModel  # noqa: E402

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
