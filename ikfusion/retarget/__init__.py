"""Retargeting human motion (a solve result, a BVH clip) onto other bodies.

Targets: the human model at another body size (``robot="human"``), the humanoid robots of
``example-robot-data`` with a shipped config under ``configs/retarget/`` (Unitree G1, Talos,
iCub, Romeo), and any humanoid URDF given by path with a config of the same keys.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..ik.settings import SolverSettings
from ..output_folders import check_output_folder
from .human import retarget_human
from .output import (
    RobotMotion,
    human_metrics,
    human_robot_motion,
    robot_metrics,
    robot_robot_motion,
    write_robot_motion,
)
from .robot import RobotRetargeter
from .robot_config import SHIPPED_ROBOTS, load_retarget_config
from .robot_model import RobotModel
from .source import HumanMotion, load_source

#: Targets ``retarget`` knows by name (any ``.urdf`` path with a config works too).
ROBOTS = ("human", *SHIPPED_ROBOTS)


def retarget(source: str | Path | HumanMotion, robot: str = "human", height: float | None = None,
             out: str | Path | None = None, gmr: bool = False, config: str | Path | None = None,
             progress: bool = False, force: bool = False, bvh_up: str = "z"
             ) -> tuple[RobotMotion, dict[str, Any]]:
    """Retarget a motion onto ``robot``; write the output folder when ``out`` is given.

    Args:
        source: A ``solve`` result folder, a BVH file, or a loaded :class:`HumanMotion`.
        robot: ``human``, a shipped robot (see :data:`ROBOTS`) or a ``.urdf`` path.
        height: Body height of a ``human`` target [m].
        out: Output folder (``robot_motion.npz``, ``.csv``, ``summary.json``; ``motion.bvh``
            for a human target).
        gmr: Also write the pickle layout of RL tracking pipelines.
        config: A retarget config replacing the shipped one (needed for a URDF path).
        progress: Show a progress bar.
        force: Replace ``out`` even when ikfusion did not write it.
        bvh_up: Up axis of the ``motion.bvh`` a human target also gets (``"z"`` or ``"y"``).

    Returns:
        The robot motion and the metrics.

    Raises:
        InputError: An unknown robot, a missing height, a bad config or a bad source (file,
            line, field).
    """
    if out is not None:
        check_output_folder(out, force)  # before the work, not after it
    if robot == "human":
        if height is None or not 0.5 < height < 2.5:
            raise InputError("a human target needs --height in metres (0.5-2.5)",
                             field="height")
        robot_config = None
    else:
        robot_config = load_retarget_config(robot, config)
    motion_in = source if isinstance(source, HumanMotion) else load_source(source)
    motion_in.check()
    start = time.perf_counter()
    if robot_config is None:
        motion = retarget_human(motion_in, height or 0.0, progress=progress)
        seconds = time.perf_counter() - start
        metrics = human_metrics(motion, motion_in, seconds,
                                SolverSettings.load().max_joint_velocity)
        metrics.update({"robot": robot, "height_m": height})
        robot_motion = human_robot_motion(motion)
    else:
        retargeter = RobotRetargeter(RobotModel(robot_config), SolverSettings.load().qp)
        start = time.perf_counter()  # frames per second of the solve, not of reading a URDF
        trajectory = retargeter.solve(motion_in, progress)
        metrics = robot_metrics(trajectory, time.perf_counter() - start)
        metrics.update({"robot": str(robot), "urdf": str(robot_config.urdf),
                        "config": str(robot_config.source)})
        robot_motion = robot_robot_motion(trajectory)
    metrics["source"] = motion_in.source
    metrics["warnings"] = [*motion_in.warnings, *metrics.get("warnings", [])]
    if out is not None:
        write_robot_motion(out, robot_motion, metrics, gmr=gmr, force=force, bvh_up=bvh_up)
    return robot_motion, metrics


__all__ = ["ROBOTS", "HumanMotion", "RobotMotion", "load_source", "retarget"]
