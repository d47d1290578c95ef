"""How a solve of an MVNX take compares with MVN's own result stored in the same file.

Both are expressed the same way before they are compared: MVN's segment orientations are
turned into our segment convention (:meth:`~ikfusion.io.mvnx.MvnxRecording.R_world_segment`),
and MVN's joint angles are recomputed from its segment orientations with OUR joint definitions
(``configs/joints.yaml``: ``R_parent_child`` decomposed into flexion, abduction, rotation), so
both sides use one angle convention. (The file's own ``jointAngle`` values follow MVN's ZXY
definitions, which differ per joint from ours; comparing those numbers directly would mix two
conventions.) Positions are not compared: the solve's world origin is where its feet stand,
MVN's is where MVN put it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..ik.pose import Motion
from ..io.mvnx import MvnxRecording
from ..rotations import angle_between

__all__ = ["compare_with_mvn"]


def _rms(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite ** 2))) if finite.size else float("nan")


def _solved_rotations(motion: Motion, segments: list[str], frames: np.ndarray) -> np.ndarray:
    """``R_world_segment`` (F, S, 3, 3) of the solve at the given frame indices."""
    model = motion.model
    data = pin.Data(model.model)
    ids = [model.segment_frame_id(s) for s in segments]
    out = np.empty((len(frames), len(segments), 3, 3))
    for row, k in enumerate(frames):
        pin.framesForwardKinematics(model.model, data, motion.q[k])
        for col, f in enumerate(ids):
            out[row, col] = data.oMf[f].rotation
    return out


def compare_with_mvn(motion: Motion, mvnx: MvnxRecording) -> dict[str, Any]:
    """Orientation and joint-angle differences between a solve and MVN's result [deg].

    Args:
        motion: The solve of ``mvnx``'s sensor orientations (frame ``k`` of the solve is the
            MVNX frame whose index is ``first index + k``).
        mvnx: The take.

    Returns:
        ``frames`` compared, ``segment_orientation_rms_deg`` (sensed and assumed segments
        apart, and per segment), ``joint_angle_rms_deg`` (joints between two sensed segments,
        all joints, and per joint: RMS over its three angles), ``mvn_beyond_our_range_share``
        (per joint, the share of frames where MVN's pose lies beyond our range of motion by
        more than 1 deg: there the solve is held at the limit) and ``warnings``.
    """
    model = motion.model
    segments = [s for s in mvnx.segments if s in model.segment_names]
    index = mvnx.frame_index - mvnx.frame_index[0]
    keep = index < len(motion)
    frames = index[keep].astype(int)
    ours = _solved_rotations(motion, segments, frames)
    theirs = np.stack([mvnx.R_world_segment(s)[keep] for s in segments], axis=1)
    diff = np.degrees(angle_between(ours, theirs))
    per_segment = {s: _rms(diff[:, k]) for k, s in enumerate(segments)}
    sensed = set(mvnx.sensors)
    column = {s: k for k, s in enumerate(segments)}
    per_joint: dict[str, float] = {}
    outside: dict[str, float] = {}
    for name, joint in model.ball_joints.items():
        parent, child = joint.spec.parent, joint.spec.child
        if parent not in column or child not in column:
            continue
        a_ours, a_theirs = (
            np.degrees(joint.spec.angles_from_rotation(
                np.swapaxes(R[:, column[parent]], -1, -2) @ R[:, column[child]]))
            for R in (ours, theirs))
        wrapped = (a_ours - a_theirs + 180.0) % 360.0 - 180.0
        per_joint[name] = _rms(wrapped)
        lower = np.array([a.lower_deg for a in joint.spec.angles])
        upper = np.array([a.upper_deg for a in joint.spec.angles])
        beyond = ((a_theirs < lower - 1.0) | (a_theirs > upper + 1.0)).any(axis=1)
        if beyond.any():
            outside[name] = float(beyond.mean())
    both_sensed = [j for j in per_joint
                   if {model.ball_joints[j].spec.parent, model.ball_joints[j].spec.child}
                   <= sensed]
    return {
        "frames": int(len(frames)),
        "segment_orientation_rms_deg": {
            "sensed": _rms(np.concatenate([diff[:, column[s]] for s in segments if s in sensed]))
            if sensed & set(segments) else None,
            "assumed": _rms(np.concatenate([diff[:, column[s]] for s in segments
                                            if s not in sensed]))
            if set(segments) - sensed else None,
            "per_segment": per_segment,
        },
        "joint_angle_rms_deg": {
            "between_sensed": _rms(np.array([per_joint[j] for j in both_sensed]))
            if both_sensed else None,
            "all": _rms(np.array(list(per_joint.values()))) if per_joint else None,
            "per_joint": per_joint,
        },
        "mvn_beyond_our_range_share": outside,
        "warnings": _warnings(per_joint, outside),
        "note": "MVN's joint angles recomputed from its segment orientations with our joint "
                "definitions (configs/joints.yaml)",
    }


def _warnings(per_joint: dict[str, float], outside: dict[str, float],
              limit_deg: float = 10.0) -> list[str]:
    """One line per joint that differs from MVN by more than ``limit_deg`` RMS, with why."""
    lines = []
    for joint, rms in per_joint.items():
        if not rms > limit_deg:
            continue
        reason = (f"; MVN's pose lies beyond our range of motion in {100 * outside[joint]:.0f} % "
                  "of the frames" if joint in outside else "")
        lines.append(f"{joint} differs from MVN's own result by {rms:.1f} deg RMS{reason}")
    return lines
