"""Sensor-to-segment calibration taken from an MVNX file: MVN's own mounting, not a new one.

An MVNX take holds, for every frame, each sensor's orientation ``R_world_sensor`` and the
orientation MVN solved for the segment it is strapped to. MVN's calibration (its N-pose or
T-pose at the start of the session, not part of the take) is therefore in the file, as the
rotation between the two:

    R_sensor_segment = R_world_sensor^T @ R_world_segment       (constant over the take)

MVN's fusion moves segments slightly against their sensors (a few degrees: soft tissue, the
biomechanical model), so the mounting is the chordal mean over every frame, and the spread
about that mean is kept for the summary. Segment frames are converted to ours (N-pose
parallel, SPEC section 1) by :meth:`ikfusion.io.mvnx.MvnxRecording.R_world_segment` first.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..io.mvnx import MvnxRecording
from ..rotations import angle_between, quat_wxyz_to_matrix
from .calibration import Calibration
from .still import mean_rotation

__all__ = ["calibration_from_mvnx"]


def calibration_from_mvnx(mvnx: MvnxRecording) -> Calibration:
    """The mounting of every sensor of an MVNX take, from MVN's own segment orientations.

    Args:
        mvnx: The take (sensor ids of its recording are the segment labels).

    Returns:
        A calibration with ``method="mvnx"``, ``heading`` the pelvis yaw in the first frame
        [rad] and ``spread_deg`` the RMS angle of the per-frame mountings about their mean.

    Raises:
        InputError: The file has no sensor orientations, or a sensor has no finite frame.
    """
    if not mvnx.sensors:
        raise InputError("the MVNX file has no sensors (no sensorOrientation data) to solve "
                         "from", path=mvnx.path, field="sensors")
    mounting: dict[str, np.ndarray] = {}
    spread: dict[str, float] = {}
    for k, segment in enumerate(mvnx.sensors):
        R_world_sensor = quat_wxyz_to_matrix(mvnx.quat_wxyz_world_sensor[:, k])
        R_world_segment = mvnx.R_world_segment(segment)
        per_frame = np.swapaxes(R_world_sensor, -1, -2) @ R_world_segment
        good = np.isfinite(per_frame).all(axis=(1, 2))
        if not good.any():
            raise InputError(f"sensor {segment} has no frame with both a sensor and a segment "
                             "orientation", path=mvnx.path, field="sensorOrientation")
        mean = mean_rotation(per_frame[good])
        mounting[segment] = mean
        deviation = np.degrees(angle_between(per_frame[good], mean))
        spread[segment] = float(np.sqrt(np.mean(deviation ** 2)))
    heading = 0.0
    if "Pelvis" in mvnx.segments:
        R0 = mvnx.R_world_segment("Pelvis")[0]
        heading = float(np.arctan2(R0[1, 0], R0[0, 0]))
    warnings = [f"{s}: MVN's segment moves {v:.1f} deg RMS against its sensor over the take"
                for s, v in spread.items() if v > 5.0]
    return Calibration(R_sensor_segment=mounting, heading=heading, window=(0, 0),
                       method="mvnx", warnings=warnings, rate=mvnx.frame_rate,
                       sensor_ids={s: s for s in mounting}, spread_deg=spread)
