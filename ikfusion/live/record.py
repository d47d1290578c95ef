"""``live --record``: the result folder of ``solve`` (SPEC section 6), written as frames arrive.

The folder gets its marker (:mod:`ikfusion.output_folders`) and a ``summary.json`` at once; the
rows of ``joint_angles.csv``, ``segments.csv``, ``sites.csv``, ``contacts.csv`` and
``solve_time.csv`` are appended and flushed every ``flush_s`` seconds of capture time, whole rows
only, and ``summary.json`` is then replaced atomically. A process killed at any moment therefore
leaves a folder that ``evaluate`` and ``view`` read, up to the last flush. ``motion.bvh`` and
``motion.mot`` (which need every frame) are written when the recording is closed.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from ..atomic import atomic_write_text
from ..ik.pose import Motion, Pose
from ..model.human_model import HumanModel
from ..output_folders import check_output_folder, write_marker
from ..results.bvh_export import write_motion_bvh
from ..results.folder import SEGMENT_COLUMNS, SITE_COLUMNS, summary
from ..results.opensim_export import write_motion_mot
from ..rotations import matrix_to_quat_wxyz
from .kinematics import PoseValues


class ResultRecorder:
    """One actor's result folder, filled frame by frame (see the module docstring).

    Args:
        folder: The result folder (replaced when ikfusion wrote it or it is empty, or with
            ``force``).
        model: The actor's model.
        contact_names: The solver's contact points (columns of ``contacts.csv``).
        flush_s: Rows are flushed this often [s of capture time].
        bvh_up: Up axis of ``motion.bvh``.
        force: Replace ``folder`` even when ikfusion did not write it.

    Raises:
        InputError: ``folder`` is refused (see :func:`ikfusion.output_folders.
            check_output_folder`).
    """

    def __init__(self, folder: str | Path, model: HumanModel, contact_names: list[str],
                 flush_s: float = 1.0, bvh_up: str = "z", force: bool = False) -> None:
        self.folder = Path(folder)
        check_output_folder(self.folder, force)
        if self.folder.exists():
            shutil.rmtree(self.folder) if self.folder.is_dir() else self.folder.unlink()
        self.folder.mkdir(parents=True)
        write_marker(self.folder, "live --record")
        self.model, self.contact_names = model, list(contact_names)
        self.flush_s, self.bvh_up = flush_s, bvh_up
        self._poses: list[Pose] = []
        self._flushed_at: float | None = None
        self._extra: dict[str, Any] = {}
        headers = {
            "joint_angles.csv": ["time", *model.angle_columns],
            "segments.csv": list(SEGMENT_COLUMNS), "sites.csv": list(SITE_COLUMNS),
            "contacts.csv": ["time", *self.contact_names],
            "solve_time.csv": ["time", "solve_time_ms", "gauss_newton_steps"]}
        self._files: dict[str, IO[str]] = {}
        self._rows: dict[str, list[str]] = {}
        for name, header in headers.items():
            self._files[name] = (self.folder / name).open("w")
            self._rows[name] = [",".join(header) + "\n"]
        self._write_summary([], complete=False)
        self._flush()

    def add(self, pose: Pose, values: PoseValues) -> None:
        """Append one solved frame (flushed every ``flush_s``)."""
        t = float(pose.time)
        self._poses.append(pose)
        rows = self._rows
        rows["joint_angles.csv"].append(_line(f"{t:.6f}", values.joint_angles_deg))
        quats = matrix_to_quat_wxyz(values.R_world_segment)
        rows["segments.csv"] += [
            _line(f"{t:.6f},{n}", np.r_[p, qt]) for n, p, qt in
            zip(self.model.segment_names, values.p_world_segment, quats)]
        rows["sites.csv"] += [_line(f"{t:.6f},{n}", p) for n, p in
                              zip(self.model.site_names, values.p_world_site)]
        rows["contacts.csv"].append(f"{t:.6f}," + ",".join(
            str(int(pose.contacts.get(c, False))) for c in self.contact_names) + "\n")
        rows["solve_time.csv"].append(f"{t:.6f},{1e3 * pose.solve_time:.4f},"
                                      f"{pose.iterations}\n")
        if self._flushed_at is None:
            self._flushed_at = t
        elif t - self._flushed_at >= self.flush_s:
            self._flushed_at = t
            self._flush()
            self._write_summary([], complete=False)

    def set_summary(self, extra: Mapping[str, Any]) -> None:
        """More ``summary.json`` keys (calibration, live counters), written at the next flush."""
        self._extra.update(extra)

    def close(self, warnings: list[str]) -> Motion:
        """Flush the rows, write ``motion.bvh``, ``motion.mot`` and the final ``summary.json``."""
        self._flush()
        for f in self._files.values():
            f.close()
        motion = self.motion(warnings)
        if len(motion):
            frame_time = 1.0 / motion.rate if motion.rate > 0 else 1.0 / 60.0
            write_motion_bvh(self.folder / "motion.bvh", self.model, motion.q, frame_time,
                             up=self.bvh_up)
            write_motion_mot(self.folder / "motion.mot", motion)
        self._write_summary(warnings, complete=True)
        return motion

    def motion(self, warnings: list[str]) -> Motion:
        """The frames recorded so far as a :class:`Motion`."""
        return Motion.from_poses(self.model, self._poses, self.contact_names, warnings)

    def _flush(self) -> None:
        """Write the pending rows (whole rows, one write per file) and flush them to the OS."""
        for name, f in self._files.items():
            if self._rows[name]:
                f.write("".join(self._rows[name]))
                f.flush()
                self._rows[name] = []

    def _write_summary(self, warnings: list[str], complete: bool) -> None:
        """``summary.json`` of the frames flushed so far, replaced atomically."""
        extra = {**self._extra, "live": {**self._extra.get("live", {}), "complete": complete}}
        atomic_write_text(self.folder / "summary.json",
                          json.dumps(summary(self.motion(warnings), extra), indent=2))


def _line(prefix: str, values: np.ndarray) -> str:
    return prefix + "," + ",".join(f"{v:.6f}" for v in values) + "\n"
