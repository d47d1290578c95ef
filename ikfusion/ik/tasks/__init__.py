"""IK tasks: each is an error and its Jacobian; the QP is assembled in ``ikfusion.ik.qp``."""

from .base import Objective, Task
from .chain import ChainShareTask, EvenChainTask
from .column_shape import ColumnShapeTask
from .damping import DampingTask
from .orientation import OrientationTask
from .position import PositionTask
from .posture import PostureTask

__all__ = ["ChainShareTask", "ColumnShapeTask", "DampingTask", "EvenChainTask", "Objective",
           "OrientationTask", "PositionTask", "PostureTask", "Task"]
