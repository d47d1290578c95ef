"""ikfusion: drift-free full-body human motion from body-worn IMUs and UWB.

The public names are re-exported here; see SPEC section 7 for the contract.
"""

from .errors import ConfigError, IkfusionError, InputError, NameNotFound, SolverError
from .ik import Frame, Motion, Pose, Solver, SolverSettings
from .model import Body, HumanModel

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
