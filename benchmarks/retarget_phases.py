"""Where a ``retarget`` command's time goes, phase by phase: the helper of ``bench_retarget.py``.

``phase_rows`` runs the steps of :func:`ikfusion.retarget.retarget` onto a robot one by one
(the same calls in the same order), each clip ``repeat`` times as a fresh command would
(``forget``: what loading clips left in this process is dropped first), and keeps the least CPU
time [ms] of each phase over the runs (other jobs on the machine only ever slow a run down):
``config`` (the output folder's check and the robot's retarget config), ``load`` (reading and
checking the source), ``setup`` (the robot model, the solver settings and the retargeter),
``solve`` (every frame, the first one's screening included), ``metrics`` and ``write`` (the
output folder).
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from ikfusion.ik.settings import SolverSettings
from ikfusion.output_folders import check_output_folder
from ikfusion.retarget import load_source
from ikfusion.retarget.output import robot_metrics, robot_robot_motion, write_robot_motion
from ikfusion.retarget.robot import RobotRetargeter
from ikfusion.retarget.robot_config import load_retarget_config
from ikfusion.retarget.robot_model import RobotModel

PHASES = ("config", "load", "setup", "solve", "metrics", "write")


def phase_times(clip: Path, robot: str, repeat: int,
                forget: Callable[[], None]) -> tuple[int, dict[str, float]]:
    """The clip's frames and the least CPU time [ms] of each phase (and ``total``)."""
    best = dict.fromkeys((*PHASES, "total"), math.inf)
    frames = 0
    for _ in range(repeat):
        forget()
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            marks = [time.process_time()]
            check_output_folder(out, False)
            config = load_retarget_config(robot, None)
            marks.append(time.process_time())
            source = load_source(clip)
            source.check()
            marks.append(time.process_time())
            retargeter = RobotRetargeter(RobotModel(config), SolverSettings.load().qp)
            marks.append(time.process_time())
            trajectory = retargeter.solve(source)
            marks.append(time.process_time())
            metrics = robot_metrics(trajectory, 1.0)
            marks.append(time.process_time())
            write_robot_motion(out, robot_robot_motion(trajectory), metrics)
            marks.append(time.process_time())
        frames = len(source)
        for name, start, stop in zip(PHASES, marks, marks[1:]):
            best[name] = min(best[name], 1e3 * (stop - start))
        best["total"] = min(best["total"], 1e3 * (marks[-1] - marks[0]))
    return frames, best


def print_phase_rows(clips: list[Path], robot: str, repeat: int,
                     forget: Callable[[], None]) -> None:
    """One row per clip: the phases' CPU milliseconds and the frames per second of the total."""
    print(f"\nphases of retarget onto {robot} (CPU ms, the least of {repeat} runs each)")
    print(f"{'clip':24} {'frames':>6} " + " ".join(f"{p:>7}" for p in (*PHASES, "total"))
          + f" {'f/s':>6}")
    for clip in clips:
        frames, best = phase_times(clip, robot, repeat, forget)
        print(f"{clip.stem[:24]:24} {frames:6d} "
              + " ".join(f"{best[p]:7.1f}" for p in (*PHASES, "total"))
              + f" {1e3 * frames / best['total']:6.0f}")
