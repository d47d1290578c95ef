"""Retargeting human motion (a solve result, a BVH clip) onto other bodies.

Today's targets: the human model at another body size (``robot="human"``). Humanoid robots
from URDFs (Unitree G1, Talos, iCub, Romeo) come with their configs under ``configs/retarget/``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..ik.settings import SolverSettings
from .human import retarget_human
from .output import RobotMotion, human_metrics, human_robot_motion, write_robot_motion
from .source import HumanMotion, load_source

#: Targets ``retarget`` knows.
ROBOTS = ("human",)


def retarget(source: str | Path | HumanMotion, robot: str = "human", height: float | None = None,
             out: str | Path | None = None, gmr: bool = False,
             progress: bool = False) -> tuple[RobotMotion, dict[str, Any]]:
    """Retarget a motion onto ``robot``; write the output folder when ``out`` is given.

    Args:
        source: A ``solve`` result folder, a BVH file, or a loaded :class:`HumanMotion`.
        robot: The target (see :data:`ROBOTS`).
        height: Body height of a ``human`` target [m].
        out: Output folder (``robot_motion.npz``, ``.csv``, ``summary.json``).
        gmr: Also write the pickle layout of RL tracking pipelines.
        progress: Show a progress bar.

    Returns:
        The robot motion and the metrics.

    Raises:
        InputError: An unknown robot, a missing height, or a bad source (file, line, field).
    """
    if robot not in ROBOTS:
        raise InputError(f"unknown robot {robot!r}; available: {', '.join(ROBOTS)}",
                         field="robot")
    if height is None or not 0.5 < height < 2.5:
        raise InputError("a human target needs --height in metres (0.5-2.5)", field="height")
    motion_in = source if isinstance(source, HumanMotion) else load_source(source)
    start = time.perf_counter()
    motion = retarget_human(motion_in, height, progress=progress)
    seconds = time.perf_counter() - start
    metrics = human_metrics(motion, motion_in, seconds, SolverSettings.load().max_joint_velocity)
    metrics.update({"robot": robot, "height_m": height, "source": motion_in.source})
    robot_motion = human_robot_motion(motion)
    if out is not None:
        write_robot_motion(out, robot_motion, metrics, gmr=gmr)
    return robot_motion, metrics


__all__ = ["ROBOTS", "HumanMotion", "RobotMotion", "load_source", "retarget"]
