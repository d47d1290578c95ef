"""Sensor-to-segment calibration from a still N-pose (or T-pose), the heading found from the data.

With ``R_world_segment = R_world_sensor @ R_sensor_segment`` and, in the N-pose, every segment
frame parallel to one body frame whose Z is up and whose X is the body's forward heading ``h``
(SPEC section 1: X forward, Y left, Z up):

    R_world_segment(N-pose) = Rz(h)   =>   R_sensor_segment = mean(R_world_sensor)^T @ Rz(h)

over a still window. The window is the stillest 1-2 s near the start (gyroscopes when recorded,
else the orientation spread) or given; a window that is not still is an error naming the
sensors that moved. No sensor mounting is assumed: ``h`` comes from the knee and hip flexion
axes in the first movements after the window (see :mod:`ikfusion.imu.heading`), checked against
the direction walked, or from the direction walked alone. ``forward={"Pelvis": "-z"}`` (the
sensor axis that points forward) overrides it; a recording with too little movement falls back
to a default mounting and says so in ``warnings``.

T-pose (``pose="tpose"``): arms straight out sideways, palms down. The trunk, legs, head and
shoulder segments are as in the N-pose (``Rz(h)``); the upper arms, forearms and hands are
rotated about the body's forward X axis, ``Rz(h) @ Rx(-90 deg)`` on the right (the arm's -Z axis
points to the body's right) and ``Rz(h) @ Rx(+90 deg)`` on the left; the palms face down.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..io.recording import ImuRecording
from ..io.sensor_map import parse_axis
from ..rotations import axis_rotation
from .heading import (
    HeadingEstimate,
    heading_from_flexion,
    walking_heading,
    world_acceleration,
)
from .still import StillThresholds, check_still, find_still_window, mean_rotation

__all__ = [
    "Calibration",
    "calibrate",
    "calibrate_recording",
    "heading_from_axis",
    "pose_rotation",
    "tpose_arm_angles_deg",
]


def tpose_arm_angles_deg() -> dict[str, float]:
    """Rotation about the body X axis [deg] of the arm segments in the T-pose."""
    return {"RightUpperArm": -90.0, "RightForeArm": -90.0, "RightHand": -90.0,
            "LeftUpperArm": 90.0, "LeftForeArm": 90.0, "LeftHand": 90.0}


def pose_rotation(segment: str, heading: float, pose: str = "npose") -> np.ndarray:
    """``R_world_segment`` (3, 3) assumed in the calibration pose.

    Args:
        segment: MVN segment name.
        heading: Body heading [rad].
        pose: ``"npose"`` or ``"tpose"``.
    """
    body = axis_rotation("z", heading)
    if pose == "tpose" and segment in tpose_arm_angles_deg():
        return body @ axis_rotation("x", np.radians(tpose_arm_angles_deg()[segment]))
    return body


@dataclass
class Calibration:
    """Result of a sensor-to-segment calibration.

    Attributes:
        R_sensor_segment: Segment -> mounting rotation (3, 3), ``R_world_segment =
            R_world_sensor @ R_sensor_segment``.
        heading: Body heading in the world at the calibration pose [rad] (0 = facing +X, East).
        window: (start, end) sample indices of the still window.
        method: How the heading was found.
        warnings: Messages for the user (fallbacks, doubts).
        pose: ``"npose"`` or ``"tpose"``.
        rate: Sample rate [Hz].
        sensor_ids: Segment -> sensor id, when known.
        spread_deg: Segment -> RMS orientation spread in the window [deg].
        estimate: The heading found from the data (also when ``forward`` overrode it), if any.
    """

    R_sensor_segment: dict[str, np.ndarray]
    heading: float
    window: tuple[int, int]
    method: str
    warnings: list[str] = field(default_factory=list)
    pose: str = "npose"
    rate: float | None = None
    sensor_ids: dict[str, str] = field(default_factory=dict)
    spread_deg: dict[str, float] = field(default_factory=dict)
    estimate: HeadingEstimate | None = None

    @property
    def heading_deg(self) -> float:
        """The heading [deg]."""
        return float(np.degrees(self.heading))

    @property
    def window_s(self) -> tuple[float, float] | None:
        """The still window in seconds, when the rate is known."""
        if self.rate is None:
            return None
        return self.window[0] / self.rate, self.window[1] / self.rate

    @property
    def R_sensor_segment_by_sensor(self) -> dict[str, np.ndarray]:
        """Sensor id -> mounting rotation (for the segments whose sensor id is known)."""
        return {self.sensor_ids[s]: R for s, R in self.R_sensor_segment.items()
                if s in self.sensor_ids}

    def segment_orientations(
            self, R_world_sensor: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``R_world_segment`` stacks (N, 3, 3) from ``R_world_sensor`` stacks per segment."""
        return {s: R @ self.R_sensor_segment[s] for s, R in R_world_sensor.items()
                if s in self.R_sensor_segment}


def heading_from_axis(R_world_sensor: np.ndarray, axis: str) -> float:
    """Heading [rad] of a sensor axis (``"x"``, ``"-z"`` ...) projected on the horizontal.

    Raises:
        InputError: A malformed axis, or one that is nearly vertical in this orientation.
    """
    try:
        k, sign = parse_axis(axis)
    except ValueError as err:
        raise InputError(str(err), field="forward") from None
    direction = sign * R_world_sensor[:, k]
    if np.hypot(direction[0], direction[1]) < 0.3:
        off = np.degrees(np.arccos(min(1.0, abs(float(direction[2])))))
        raise InputError(f"the sensor axis {axis} is within {off:.0f} deg of vertical in the "
                         "calibration pose: it cannot give the heading; name a horizontal axis",
                         field="forward")
    return float(np.arctan2(direction[1], direction[0]))


def _angle_deg(a: float, b: float) -> float:
    return float(np.degrees(abs(np.angle(np.exp(1j * (a - b))))))


def _heading(mean: Mapping[str, np.ndarray], R_world_sensor: Mapping[str, np.ndarray],
             window: tuple[int, int], rate: float, forward: Mapping[str, str] | None,
             default_forward: Mapping[str, str] | None,
             acc_world: np.ndarray | None) -> tuple[float, str, list[str],
                                                    HeadingEstimate | None]:
    warnings: list[str] = []
    estimate = heading_from_flexion(R_world_sensor, window, rate)
    walk = None if acc_world is None else walking_heading(acc_world, window, rate)
    if estimate is not None:
        warnings += estimate.warnings
        if walk is not None:
            estimate.walk_heading = walk[0]
            off = _angle_deg(walk[0], estimate.heading)
            if off > 60.0:
                warnings.append(f"the direction walked ({np.degrees(walk[0]):.0f} deg, "
                                f"{walk[1]:.1f} m/s) is {off:.0f} deg off the heading of the "
                                f"knee/hip flexion axis ({np.degrees(estimate.heading):.0f} deg)"
                                ": walking backwards or sideways, or a sensor map error?")
    if forward:
        if len(forward) != 1:
            raise InputError("forward names one segment and its sensor axis, e.g. "
                             "{'Pelvis': '-z'}", field="forward")
        segment, axis = next(iter(forward.items()))
        if segment not in mean:
            raise InputError(f"forward names {segment}, which has no sensor; segments: "
                             f"{', '.join(mean)}", field="forward")
        heading = heading_from_axis(mean[segment], axis)
        if estimate is not None and _angle_deg(heading, estimate.heading) > 45.0:
            warnings.append(f"forward {segment}:{axis} gives a heading "
                            f"{_angle_deg(heading, estimate.heading):.0f} deg off the knee/hip "
                            "flexion axis; the override is used")
        return heading, f"forward {segment}:{axis}", warnings, estimate
    if estimate is not None:
        return estimate.heading, estimate.method, warnings, estimate
    if walk is not None:
        return walk[0], f"direction walked ({walk[1]:.1f} m/s)", warnings, None
    defaults = dict(default_forward or {})
    if not defaults:
        reference = "Pelvis" if "Pelvis" in mean else next(iter(mean))
        defaults = {reference: "-z"}
    segment, axis = next(iter(defaults.items()))
    if segment not in mean:
        raise InputError(f"too little movement to find the heading, and the default mounting "
                         f"names {segment}, which has no sensor; give forward=", field="forward")
    try:
        heading = heading_from_axis(mean[segment], axis)
    except InputError as err:
        raise InputError(f"too little knee/hip movement or walking after the calibration pose "
                         f"to find the body heading, and the default mounting cannot give it: "
                         f"{err.reason}; give forward= (--forward SEGMENT:AXIS)",
                         field="forward") from None
    warnings.append("too little knee/hip movement or walking after the calibration pose to "
                    f"find the body heading; assumed the {segment} sensor's {axis} axis points "
                    "forward (the default mounting; give --forward SEGMENT:AXIS to say how it is "
                    "mounted)")
    return heading, f"fallback: {segment} sensor {axis} axis forward", warnings, None


def calibrate(R_world_sensor: Mapping[str, np.ndarray], rate: float,
              window: tuple[int, int] | None = None, forward: Mapping[str, str] | None = None,
              pose: str = "npose", *, gyr: Mapping[str, np.ndarray | None] | None = None,
              acc: Mapping[str, np.ndarray | None] | None = None,
              free_acc: Mapping[str, np.ndarray | None] | None = None,
              default_forward: Mapping[str, str] | None = None,
              thresholds: StillThresholds | None = None, search: float = 10.0,
              sensor_ids: Mapping[str, str] | None = None) -> Calibration:
    """Sensor-to-segment rotations from a still pose near the start of a recording.

    Args:
        R_world_sensor: Segment -> its sensor's orientations (N, 3, 3), ENU world.
        rate: Sample rate [Hz].
        window: (start, end) sample indices of the still pose; the stillest 2 s (else 1.5 s,
            1 s) of the first ``search`` seconds when omitted.
        forward: ``{segment: axis}``, the sensor axis that points forward (e.g. ``"-z"``);
            overrides the heading found from the data.
        pose: ``"npose"`` or ``"tpose"`` (see the module docstring for the T-pose).
        gyr: Segment -> (N, 3) angular rate [rad/s], to find and check the still window.
        acc: Segment -> (N, 3) specific force in the sensor frame [m/s^2] (Pelvis or T8 give
            the direction walked).
        free_acc: Segment -> (N, 3) world acceleration without gravity [m/s^2] (preferred to
            ``acc`` for the direction walked).
        default_forward: The mounting assumed when nothing else decides the heading, e.g.
            ``{"Pelvis": "x"}``; the pelvis sensor's -z axis (a sensor flat on the sacrum)
            when omitted.
        thresholds: What still means.
        search: Seconds from the start searched for the still window.
        sensor_ids: Segment -> sensor id, kept in the result.

    Returns:
        The :class:`Calibration`.

    Raises:
        InputError: A bad pose, a window that is not still (naming the sensors that moved), no
            still window, a bad ``forward``.
    """
    if pose not in ("npose", "tpose"):
        raise InputError(f"pose must be npose or tpose, not {pose!r}", field="calibrate")
    if not R_world_sensor:
        raise InputError("no sensor orientations to calibrate", field="sensors")
    win = window if window is not None else find_still_window(
        R_world_sensor, rate, gyr, search=search, thresholds=thresholds)
    spread = check_still(R_world_sensor, win, rate, gyr, thresholds)
    mean = {s: mean_rotation(R[win[0]:win[1]]) for s, R in R_world_sensor.items()}
    acc_world = None
    for trunk in ("Pelvis", "T8", "L5", "L3", "T12"):
        if trunk in R_world_sensor:
            acc_world = world_acceleration(R_world_sensor[trunk],
                                           None if acc is None else acc.get(trunk),
                                           None if free_acc is None else free_acc.get(trunk))
            if acc_world is not None:
                break
    heading, method, warnings, estimate = _heading(mean, R_world_sensor, win, rate, forward,
                                                   default_forward, acc_world)
    R_sensor_segment = {s: R.T @ pose_rotation(s, heading, pose) for s, R in mean.items()}
    return Calibration(R_sensor_segment, heading, (int(win[0]), int(win[1])), method, warnings,
                       pose, rate, dict(sensor_ids or {}), spread, estimate)


def calibrate_recording(recording: ImuRecording, sensor_map: Mapping[str, str],
                        window_s: tuple[float, float] | None = None,
                        forward: Mapping[str, str] | None = None, pose: str = "npose",
                        default_forward: Mapping[str, str] | None = None,
                        thresholds: StillThresholds | None = None) -> Calibration:
    """Calibrate the mapped sensors of a recording (gyroscopes and accelerations used if any).

    Args:
        recording: The recording.
        sensor_map: Sensor id -> segment (a :class:`ikfusion.io.SensorMap` also brings its
            ``forward`` default mounting).
        window_s: (t0, t1) [s] of the still pose; found automatically when omitted.
        forward: ``{segment: axis}`` override of the heading.
        pose: ``"npose"`` or ``"tpose"``.
        default_forward: Mounting assumed when the data cannot decide (default: the map's
            ``forward``, else the pelvis sensor's -z axis).
        thresholds: What still means.

    Raises:
        InputError: Mapped sensors missing, a window that is not still, etc.
    """
    streams = recording.segment_streams(sensor_map)
    window = None
    if window_s is not None:
        t0, t1 = window_s
        if not 0.0 <= t0 < t1:
            raise InputError(f"the calibration window needs 0 <= t0 < t1, got {t0:g}:{t1:g}",
                             field="calibrate")
        window = (int(round(t0 * recording.rate)), int(round(t1 * recording.rate)))
    defaults = default_forward if default_forward is not None else getattr(sensor_map,
                                                                           "forward", None)
    return calibrate(
        {s: st.R_world_sensor for s, st in streams.items()}, recording.rate, window, forward,
        pose, gyr={s: st.gyr for s, st in streams.items()},
        acc={s: st.acc for s, st in streams.items()},
        free_acc={s: st.free_acc for s, st in streams.items()}, default_forward=defaults,
        thresholds=thresholds, sensor_ids={s: st.sensor_id for s, st in streams.items()})
