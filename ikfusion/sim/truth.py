"""Ground truth of a simulated capture, and writing its ``truth.npz`` file (SPEC section 5).

The motion itself is a :class:`ikfusion.mocap.model_motion.TruthMotion`; the file is read by
:func:`ikfusion.io.truth_npz.read_truth`.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..atomic import atomic_write
from ..ik.frame import Frame
from ..imu.stance import foot_still
from ..mocap.model_motion import TruthMotion, segment_poses, site_positions
from ..model.human_model import HumanModel
from ..rotations import matrix_to_quat_wxyz


def orientation_frames(model: HumanModel, q: np.ndarray, time: np.ndarray,
                       segments: list[str] | tuple[str, ...],
                       stacked: bool = False) -> list[Frame]:
    """Solver frames whose targets are the exact segment orientations along ``q`` (N, nq).

    ``stacked``: each frame also holds its orientations as one (k, 3, 3) array
    (``Frame.orientations_stacked``, the mapping's values views of it), as the application's
    frames do; such a frame's orientations must not be changed in place.
    """
    data = model.model.createData()
    ids = [model.segment_frame_id(s) for s in segments]
    frames = []
    for t, qk in zip(time, q):
        pin.framesForwardKinematics(model.model, data, qk)
        R = np.array([data.oMf[f].rotation for f in ids])
        frames.append(Frame(float(t), dict(zip(segments, R)),
                            orientations_stacked=R if stacked else None))
    return frames


def write_truth(path: str | Path, truth: TruthMotion) -> Path:
    """Write ``truth.npz``: time, q, segment poses, site positions and contact phases.

    Keys: ``time`` (N,) [s]; ``q`` (N, nq); ``segment_names``; ``p_world_segment`` (N, S, 3)
    [m]; ``quat_wxyz_world_segment`` (N, S, 4); ``site_names``; ``p_world_site`` (N, M, 3) [m];
    ``contact_names``; ``contacts`` (N, k) bool; ``joint_angle_names`` and ``joint_angles``
    (N, 66) [deg]; ``source``; with ``info["area_fit"]`` (where ``simulate --readers`` put
    the motion in the capture area, see :mod:`ikfusion.sim.area_fit`) also ``area_fit``, that
    mapping as a JSON string.
    """
    model = truth.model
    segments = model.segment_names
    sites = model.site_names
    p_seg, R_seg = segment_poses(model, truth.q)
    extra: dict[str, Any] = {}
    if "area_fit" in truth.info:
        extra["area_fit"] = np.array(json.dumps(truth.info["area_fit"]))
    with atomic_write(path, "wb") as out:
        np.savez_compressed(
            out, time=truth.time, q=truth.q, segment_names=np.array(segments),
            p_world_segment=p_seg, quat_wxyz_world_segment=matrix_to_quat_wxyz(R_seg),
            site_names=np.array(sites), p_world_site=site_positions(model, truth.q, sites),
            contact_names=np.array(truth.contact_names), contacts=truth.contacts,
            joint_angle_names=np.array(model.angle_columns),
            joint_angles=model.joint_angle_matrix(truth.q), source=np.array(truth.source),
            **extra)
    return Path(path)


def with_feet_still(frames: list[Frame], rate: float) -> list[Frame]:
    """The frames with the feet's stance added.

    Stance comes from the feet's orientations (:func:`ikfusion.imu.stance.foot_still`), as the
    pipeline finds it from foot IMUs.
    """
    out = list(frames)
    for foot in ("LeftFoot", "RightFoot"):
        R = np.array([f.orientations.get(foot, np.full((3, 3), np.nan)) for f in frames])
        still = foot_still(R, rate)
        out = [replace(f, feet_still={**f.feet_still, foot: bool(s)}) if np.isfinite(s) else f
               for f, s in zip(out, still)]
    return out
