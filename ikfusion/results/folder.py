"""The result folder of ``solve`` (SPEC section 6), written atomically.

Files: ``joint_angles.csv`` (time, then ``<joint>_flex/_abd/_rot`` [deg]), ``segments.csv``
(``time,segment,px,py,pz,qw,qx,qy,qz``; world frame, Z up, metres), ``sites.csv``
(``time,site,x,y,z``), ``contacts.csv`` (``time,LeftHeel,LeftToe,RightHeel,RightToe`` as 0/1),
``motion.bvh``, ``motion.mot`` (OpenSim coordinates of the Rajagopal 2015 model, degrees and
metres, Y up; mapping in ``configs/opensim.yaml``, see :mod:`.opensim_export`),
``solve_time.csv`` (``time,solve_time_ms,gauss_newton_steps`` per frame; beyond SPEC section 6,
for the viewer's timeline) and ``summary.json`` (frames, rate, solve time per frame, warnings).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_folder
from ..ik.pose import Motion
from .bvh_export import write_motion_bvh
from .opensim_export import write_motion_mot
from .result_kinematics import ResultKinematics
from .text_table import long_rows, write_csv

#: The files of a result folder (besides the hidden marker of :mod:`ikfusion.output_folders`).
RESULT_FILES = ("joint_angles.csv", "segments.csv", "sites.csv", "contacts.csv", "solve_time.csv",
                "motion.bvh", "motion.mot", "summary.json")
SEGMENT_COLUMNS = ("time", "segment", "px", "py", "pz", "qw", "qx", "qy", "qz")
SITE_COLUMNS = ("time", "site", "x", "y", "z")


def _write_long_csv(path: Path, header: tuple[str, ...], time: np.ndarray, names: list[str],
                    values: np.ndarray) -> None:
    """Rows ``time,name,v0,v1,...`` for every frame and name; ``values`` is (N, names, k)."""
    with path.open("wb") as out:
        out.write((",".join(header) + "\n").encode())
        long_rows(out, time, names, values)


def summary(motion: Motion, extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The ``summary.json`` content."""
    ms = 1e3 * motion.solve_time
    out: dict[str, Any] = {
        "frames": len(motion),
        "rate": motion.rate,
        "duration_s": float(motion.time[-1] - motion.time[0]) if len(motion) else 0.0,
        "solve_time_ms_mean": float(ms.mean()) if len(ms) else 0.0,
        "solve_time_ms_p95": float(np.percentile(ms, 95)) if len(ms) else 0.0,
        "gauss_newton_steps_mean": float(motion.iterations.mean()) if len(motion) else 0.0,
        "relaxed_frames": int(motion.relaxed.sum()),
        "warnings": list(motion.warnings),
    }
    out.update(extra or {})
    return out


def write_result_folder(motion: Motion, out_dir: str | Path, bvh_up: str = "z",
                        extra_summary: Mapping[str, Any] | None = None,
                        force: bool = False) -> Path:
    """Write the result folder of a solved motion; it appears whole or not at all.

    Args:
        motion: The solved motion.
        out_dir: The folder (replacing one ikfusion wrote, or any with ``force``).
        bvh_up: Up axis of ``motion.bvh`` (``"z"`` or ``"y"``).
        extra_summary: More keys for ``summary.json`` (calibration, UWB usage, ...).
        force: Replace ``out_dir`` even when ikfusion did not write it.

    Raises:
        InputError: ``out_dir`` exists and is not an ikfusion output (without ``force``).

    Returns:
        The folder.
    """
    model = motion.model
    kinematics = ResultKinematics.of(motion)
    quat_seg = kinematics.segment_quats_wxyz()
    with atomic_folder(out_dir, "solve", force) as tmp:
        write_csv(tmp / "joint_angles.csv", ["time", *model.angle_columns],
                  ["%.6f"] * (1 + len(model.angle_columns)),
                  np.column_stack([motion.time, kinematics.angles]))
        _write_long_csv(tmp / "segments.csv", SEGMENT_COLUMNS, motion.time, model.segment_names,
                        np.concatenate([kinematics.p_world_segment, quat_seg], axis=2))
        _write_long_csv(tmp / "sites.csv", SITE_COLUMNS, motion.time, model.site_names,
                        kinematics.p_world_site)
        write_csv(tmp / "contacts.csv", ["time", *motion.contact_names],
                  ["%.6f"] + ["%d"] * len(motion.contact_names),
                  np.column_stack([motion.time, motion.contacts.astype(int)]))
        write_csv(tmp / "solve_time.csv", ["time", "solve_time_ms", "gauss_newton_steps"],
                  ["%.6f", "%.4f", "%d"],
                  np.column_stack([motion.time, 1e3 * motion.solve_time, motion.iterations]))
        frame_time = 1.0 / motion.rate if motion.rate > 0 else 1.0 / 60.0
        write_motion_bvh(tmp / "motion.bvh", model, motion.q, frame_time, up=bvh_up,
                         rotations=kinematics.R_parent_segment)
        write_motion_mot(tmp / "motion.mot", motion, kinematics=kinematics)
        (tmp / "summary.json").write_text(json.dumps(summary(motion, extra_summary), indent=2))
    return Path(out_dir)
