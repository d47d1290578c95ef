"""Sensor-to-segment calibration from a still N-pose (or T-pose), heading found from the data.

In the N-pose every segment frame is parallel to one body frame whose Z is up and whose X is the
body's forward heading ``h`` (SPEC section 1), so from the mean sensor orientation in a still
window:

    R_world_segment = R_world_sensor @ R_sensor_segment,   R_world_segment(N-pose) = Rz(h)
    => R_sensor_segment = R_world_sensor(window)^T @ Rz(h)

No sensor mounting is assumed. The heading comes from the first movements after the window:
knees flex about the segment Y axis (left), always toward positive flexion, so the dominant
axis of the thigh-to-shank relative rotation, seen from the thigh sensor at the N-pose, is the
body's left direction in the world (hips also abduct and rotate while walking, so they are not
used). ``forward``
overrides it (``{"Pelvis": "-z"}``: the pelvis sensor's -z axis points forward); a recording
with too little movement falls back to the pelvis sensor's -z axis and says so.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..rotations import (
    angle_between,
    axis_rotation,
    log_so3,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
)

_KNEES = (("RightUpperLeg", "RightLowerLeg"), ("LeftUpperLeg", "LeftLowerLeg"))
_AXES = {"x": 0, "y": 1, "z": 2}
#: T-pose: arm segments abducted 90 deg, palms down (rotation about the body X axis).
_TPOSE = {"RightUpperArm": -90.0, "RightForeArm": -90.0, "RightHand": -90.0,
          "LeftUpperArm": 90.0, "LeftForeArm": 90.0, "LeftHand": 90.0}


@dataclass
class Calibration:
    """Result of a sensor-to-segment calibration.

    Attributes:
        R_sensor_segment: Segment -> mounting rotation (3, 3).
        heading: Body heading in the world at the calibration pose [rad] (0 = facing +X).
        window: (start, end) sample indices of the still window.
        method: How the heading was found.
        warnings: Messages for the user (fallbacks).
    """

    R_sensor_segment: dict[str, np.ndarray]
    heading: float
    window: tuple[int, int]
    method: str
    warnings: list[str] = field(default_factory=list)

    def segment_orientations(
            self, R_world_sensor: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``R_world_segment`` stacks (N, 3, 3) from ``R_world_sensor`` stacks per segment."""
        return {s: R @ self.R_sensor_segment[s] for s, R in R_world_sensor.items()
                if s in self.R_sensor_segment}


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """Chordal mean of rotations (k, 3, 3) (NaN entries ignored)."""
    good = np.isfinite(R).all(axis=(1, 2))
    q = matrix_to_quat_wxyz(R[good])
    q *= np.sign(q @ q[0])[:, None]
    return quat_wxyz_to_matrix(q.mean(axis=0))


def find_still_window(R_world_sensor: Mapping[str, np.ndarray], rate: float,
                      seconds: float = 1.0, search: float = 6.0) -> tuple[int, int]:
    """The stillest ``seconds`` long window within the first ``search`` seconds.

    Stillness is the summed orientation change of all sensors between consecutive samples.
    """
    n = min(len(R) for R in R_world_sensor.values())
    width = max(2, int(round(seconds * rate)))
    limit = min(n, max(width + 1, int(round(search * rate))))
    motion = np.zeros(limit - 1)
    for R in R_world_sensor.values():
        step = angle_between(R[:limit - 1], R[1:limit])
        motion += np.nan_to_num(step, nan=1.0)
    if len(motion) < width:
        raise InputError(f"the recording is shorter than a {seconds:.1f} s calibration window")
    cumulative = np.concatenate([[0.0], np.cumsum(motion)])
    sums = cumulative[width:] - cumulative[:-width]
    start = int(np.argmin(sums))
    return start, start + width


def _check_still(R_world_sensor: Mapping[str, np.ndarray], window: tuple[int, int],
                 max_spread_deg: float) -> None:
    moved = []
    for segment, R in R_world_sensor.items():
        block = R[window[0]:window[1]]
        if not np.isfinite(block).all(axis=(1, 2)).any():
            moved.append(f"{segment} (no data)")
            continue
        spread = np.degrees(np.sqrt(np.nanmean(angle_between(block, mean_rotation(block)) ** 2)))
        if spread > max_spread_deg:
            moved.append(f"{segment} ({spread:.1f} deg)")
    if moved:
        raise InputError(f"the calibration window is not still: {', '.join(moved)} moved more "
                         f"than {max_spread_deg:.1f} deg; give a still window (--calibrate T0:T1)",
                         field="calibrate")


def _flexion_axis(R_parent: np.ndarray, R_child: np.ndarray, window: tuple[int, int],
                  horizon: int) -> tuple[np.ndarray, float] | None:
    """World direction of the dominant relative-rotation axis after the window.

    Also returns its RMS amplitude [deg]; the direction points so that most rotations are
    positive about it.
    """
    end = min(len(R_parent), window[1] + horizon)
    P0 = mean_rotation(R_parent[window[0]:window[1]])
    A0 = P0.T @ mean_rotation(R_child[window[0]:window[1]])
    A = np.swapaxes(R_parent[window[1]:end], 1, 2) @ R_child[window[1]:end]
    good = np.isfinite(A).all(axis=(1, 2))
    if good.sum() < 10:
        return None
    v = log_so3(A[good] @ A0.T)  # in the parent sensor frame
    eigenvalues, vectors = np.linalg.eigh(v.T @ v / len(v))
    axis = vectors[:, -1]
    if np.mean(v @ axis) < 0:
        axis = -axis
    return P0 @ axis, float(np.degrees(np.sqrt(eigenvalues[-1])))


def _heading_from_flexion(R: Mapping[str, np.ndarray], window: tuple[int, int],
                          rate: float) -> tuple[float, float] | None:
    horizon = int(10 * rate)
    left, amplitude = None, 0.0
    for parent, child in _KNEES:
        if parent in R and child in R:
            found = _flexion_axis(R[parent], R[child], window, horizon)
            if found is not None and found[1] > 10.0:
                left = found[0] if left is None else left + found[0]
                amplitude = max(amplitude, found[1])
    if left is None:
        return None
    left[2] = 0.0
    if np.linalg.norm(left) < 1e-6:
        return None
    left /= np.linalg.norm(left)
    forward = np.cross(left, [0.0, 0.0, 1.0])
    return float(np.arctan2(forward[1], forward[0])), amplitude


def _heading_from_axis(R_sensor: np.ndarray, axis_spec: str) -> float:
    text = axis_spec.strip().lower()
    sign = -1.0 if text.startswith("-") else 1.0
    letter = text.lstrip("+-")
    if letter not in _AXES:
        raise InputError(f"forward axis must be x, y or z with an optional sign, not "
                         f"{axis_spec!r}", field="forward")
    forward = R_sensor @ (sign * np.eye(3)[_AXES[letter]])
    if np.hypot(forward[0], forward[1]) < 0.2:
        raise InputError(f"the sensor axis {axis_spec} is nearly vertical in the calibration "
                         "pose: it cannot give the heading", field="forward")
    return float(np.arctan2(forward[1], forward[0]))


def calibrate(R_world_sensor: Mapping[str, np.ndarray], rate: float,
              window: tuple[int, int] | None = None, forward: Mapping[str, str] | None = None,
              pose: str = "npose", max_spread_deg: float = 3.0) -> Calibration:
    """Sensor-to-segment rotations from a still pose at the start of a recording.

    Args:
        R_world_sensor: Segment -> its sensor's orientations (N, 3, 3), ENU world.
        rate: Sample rate [Hz].
        window: (start, end) sample indices of the still pose; the stillest second of the
            first six when omitted.
        forward: ``{segment: axis}``, the sensor axis that points forward (e.g. ``"-z"``).
        pose: ``"npose"`` or ``"tpose"`` (arms abducted 90 deg, palms down).
        max_spread_deg: Largest RMS orientation spread of a still sensor [deg].

    Raises:
        InputError: A window that is not still (naming the sensors that moved), a bad pose.
    """
    if pose not in ("npose", "tpose"):
        raise InputError(f"pose must be npose or tpose, not {pose!r}", field="calibrate")
    win = window if window is not None else find_still_window(R_world_sensor, rate)
    _check_still(R_world_sensor, win, max_spread_deg)
    mean = {s: mean_rotation(R[win[0]:win[1]]) for s, R in R_world_sensor.items()}
    warnings: list[str] = []
    if forward:
        segment, axis = next(iter(forward.items()))
        if segment not in mean:
            raise InputError(f"--forward names {segment}, which has no sensor", field="forward")
        heading, method = _heading_from_axis(mean[segment], axis), f"forward {segment}:{axis}"
    else:
        found = _heading_from_flexion(R_world_sensor, win, rate)
        if found is not None:
            heading, method = found[0], f"knee flexion axis ({found[1]:.0f} deg of motion)"
        else:
            reference = "Pelvis" if "Pelvis" in mean else next(iter(mean))
            heading = _heading_from_axis(mean[reference], "-z")
            method = f"fallback: {reference} sensor -z axis forward"
            warnings.append("too little knee movement after the calibration pose to find the "
                            f"body heading; assumed the {reference} sensor's -z axis points "
                            "forward (use --forward SEGMENT:AXIS to say how it is mounted)")
    body = axis_rotation("z", heading)
    R_sensor_segment = {}
    for segment, R in mean.items():
        R_segment = body
        if pose == "tpose" and segment in _TPOSE:
            R_segment = body @ axis_rotation("x", np.radians(_TPOSE[segment]))
        R_sensor_segment[segment] = R.T @ R_segment
    return Calibration(R_sensor_segment, heading, win, method, warnings)
