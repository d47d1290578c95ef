"""Whole-body inverse kinematics: tasks, limits, the QP of one step, and the frame solver."""

from .configuration import Configuration
from .frame import Frame
from .pose import Motion, Pose
from .qp import QpProblem, QpSettings, QpSolution, build_qp, solve_qp
from .settings import SolverSettings
from .solver import Solver

__all__ = [
    "Configuration",
    "Frame",
    "Motion",
    "Pose",
    "QpProblem",
    "QpSettings",
    "QpSolution",
    "Solver",
    "SolverSettings",
    "build_qp",
    "solve_qp",
]
