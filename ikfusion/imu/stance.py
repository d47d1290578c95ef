"""Stance of a foot from its IMU: the foot is flat on the floor while its sensor does not turn.

In walking and running a foot in stance is still for a tenth of a second or more, while a swinging
foot turns at several rad/s (it passes through low rates only for an instant). A foot is
therefore *still* where its angular speed stays below a threshold for at least a minimum
duration. The angular speed comes from the gyroscope when recorded (it is the same in every
frame, so no calibration is needed); otherwise from successive orientations, which is only as
good as the orientation output is smooth.

A foot can also stop turning while it still travels: a side step carries the foot sideways,
level, and lowers it onto the floor with hardly any rotation, so the angular speed alone says
*still* some 100 ms before the foot lands. When the accelerometer is recorded, a still foot must
therefore also have a calm acceleration: the sensor's acceleration in the world with gravity
removed (``R_world_sensor f + g``) stays small while the foot stands, and is large while a
travelling foot is braked onto the floor (heel strike, the end of a side step).

This is what pedestrian dead reckoning calls a zero-velocity detector; the solver uses it to keep
a still foot planted and to hand the body over to it from a foot that moves (see
:mod:`ikfusion.ik.contacts`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..rotations import log_so3
from .flight import world_acceleration

if TYPE_CHECKING:
    from ..ik.settings import SolverSettings


@dataclass(frozen=True)
class StanceThresholds:
    """What a still foot means.

    Attributes:
        max_rate: Angular speed below which the foot may be still [rad/s].
        min_duration: Shortest still stretch that counts [s] (a swinging foot passes through
            low rates only for an instant).
        window: Width of the running maximum taken over the angular speed [s].
        max_acceleration: Acceleration without gravity (world frame) below which the foot may
            be still, when the accelerometer is recorded [m/s^2] (a side step braked onto
            the floor shows 5-10 m/s^2 until it lands; a foot standing on a jittery mocap
            clip up to 3).
        rolling_rate: Angular speed below which a foot that never stands still in a stance
            (it rolls from heel to ball all along, as in a brisk walk) is taken as at rest at its
            slowest sample, for the velocity of :mod:`ikfusion.imu.point_speed` only [rad/s]:
            turning at 1 rad/s about its ball, 6 cm away, the sensor moves at 0.06 m/s, under
            the speed that says a point moves (``release_speed``, 0.1 m/s).
    """

    max_rate: float = 0.6
    min_duration: float = 0.1
    window: float = 0.05
    max_acceleration: float = 3.0
    rolling_rate: float = 1.0


def stance_thresholds(settings: SolverSettings) -> StanceThresholds:
    """The thresholds of a :class:`ikfusion.ik.SolverSettings` (its ``still_*`` keys)."""
    return StanceThresholds(max_rate=settings.still_rate, min_duration=settings.still_duration,
                            max_acceleration=settings.still_acceleration,
                            rolling_rate=settings.rolling_rate)


def free_acceleration(R_world_sensor: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """|a| [m/s^2] per sample: the sensor's acceleration in the world without gravity.

    Args:
        R_world_sensor: (N, 3, 3) orientations (NaN where missing).
        acc: (N, 3) specific force in the sensor frame [m/s^2] (NaN where missing).

    Returns:
        (N,) the magnitude of ``R_world_sensor acc + g``, NaN where unknown.
    """
    return np.linalg.norm(world_acceleration(R_world_sensor, acc), axis=1)


def angular_speed(R_world_sensor: np.ndarray, rate: float, gyr: np.ndarray | None = None
                  ) -> np.ndarray:
    """|omega| [rad/s] per sample, from the gyroscope when given, else from the orientations.

    Args:
        R_world_sensor: (N, 3, 3) orientations (NaN where missing).
        rate: Sample rate [Hz].
        gyr: (N, 3) angular rate in the sensor frame [rad/s], or None.

    Returns:
        (N,) angular speed, NaN where unknown.
    """
    if gyr is not None:
        return np.linalg.norm(np.asarray(gyr, dtype=float), axis=1)
    n = len(R_world_sensor)
    speed = np.full(n, np.nan)
    if n < 2:
        return speed
    R = np.asarray(R_world_sensor, dtype=float)
    good = np.isfinite(R).all(axis=(1, 2))
    pair = good[:-1] & good[1:]
    step = np.full(n - 1, np.nan)
    relative = np.swapaxes(R[:-1][pair], -1, -2) @ R[1:][pair]
    step[pair] = np.linalg.norm(log_so3(relative), axis=-1) * rate
    speed[1:-1] = np.fmax(step[:-1], step[1:])  # the larger neighbour: never hides a turn
    speed[0], speed[-1] = step[0], step[-1]
    return speed


def _running_max(x: np.ndarray, width: int) -> np.ndarray:
    """Centred running maximum over ``width`` samples; NaN counts as large."""
    padded = np.pad(np.nan_to_num(x, nan=np.inf), width // 2, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * (width // 2) + 1)
    return windows.max(axis=1)[: len(x)]


def _drop_short_runs(mask: np.ndarray, min_length: int) -> np.ndarray:
    """``mask`` without its True runs shorter than ``min_length`` samples."""
    out = mask.copy()
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    for start, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        if end - start < min_length:
            out[start:end] = False
    return out


def foot_still(R_world_sensor: np.ndarray, rate: float, gyr: np.ndarray | None = None,
               thresholds: StanceThresholds | None = None,
               acc: np.ndarray | None = None) -> np.ndarray:
    """Where a foot IMU says the foot stands still (offline: looks ahead ``min_duration``).

    Args:
        R_world_sensor: (N, 3, 3) the foot sensor's orientations (ENU world).
        rate: Sample rate [Hz].
        gyr: (N, 3) its angular rate [rad/s] in the sensor frame, when recorded.
        thresholds: What still means.
        acc: (N, 3) its specific force [m/s^2] in the sensor frame, when recorded: the
            acceleration must be calm too (samples without it are judged by the rate alone).

    Returns:
        (N,) 1.0 still, 0.0 moving, NaN unknown (no valid sample there). A gap of up to
        ``min_duration`` inside a still stretch does not cut it (its speed is taken as the
        larger on either side).
    """
    th = thresholds or StanceThresholds()
    min_length = max(1, int(round(th.min_duration * rate)))
    speed = angular_speed(R_world_sensor, rate, gyr)
    width = max(1, int(round(th.window * rate)))
    calm = _running_max(_bridge_short_gaps(speed, min_length), width) < th.max_rate
    if acc is not None:
        accel = free_acceleration(R_world_sensor, acc)
        if np.isfinite(accel).any():
            accel = np.where(np.isfinite(accel), accel, 0.0)  # unknown: the rate decides
            calm &= _running_max(accel, width) < th.max_acceleration
    still = _drop_short_runs(calm, min_length)
    out = still.astype(float)
    out[~np.isfinite(speed)] = np.nan
    return out


def velocity_anchors(R_world_sensor: np.ndarray, still: np.ndarray, rate: float,
                     gyr: np.ndarray | None = None, thresholds: StanceThresholds | None = None,
                     acc: np.ndarray | None = None) -> np.ndarray:
    """Samples where a foot's sensor velocity may be taken as zero (zero-velocity updates).

    The still samples (:func:`foot_still`), and in each stance where the foot never stands
    still (it turns slower than ``rolling_rate`` with a calm acceleration for ``min_duration``
    but not slower than ``max_rate``) the single sample where it turns slowest: a foot rolling
    over its stance in a brisk walk is never still by the stance thresholds, and without an
    anchor its points' speeds would stay unknown from stride to stride.

    Args:
        R_world_sensor: (N, 3, 3) the foot sensor's orientations (NaN where missing).
        still: (N,) where the foot stands still.
        rate: Sample rate [Hz].
        gyr: (N, 3) its angular rate [rad/s], sensor frame, when recorded.
        thresholds: What still means (``rolling_rate``, ``max_acceleration``, ``min_duration``).
        acc: (N, 3) its specific force [m/s^2], sensor frame, when recorded.

    Returns:
        (N,) True at the anchors.
    """
    th = thresholds or StanceThresholds()
    anchors = np.asarray(still, dtype=bool).copy()
    speed = angular_speed(R_world_sensor, rate, gyr)
    calm = np.where(np.isfinite(speed), speed, np.inf) < th.rolling_rate
    if acc is not None:
        accel = free_acceleration(R_world_sensor, acc)
        calm &= np.where(np.isfinite(accel), accel, np.inf) < th.max_acceleration
    calm = _drop_short_runs(calm, max(1, int(round(th.min_duration * rate))))
    edges = np.diff(np.r_[0, calm.astype(np.int8), 0])
    for start, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        if not anchors[start:end].any():
            anchors[start + int(np.argmin(speed[start:end]))] = True
    return anchors


def _bridge_short_gaps(speed: np.ndarray, max_length: int) -> np.ndarray:
    """``speed`` with short unknown runs (lost samples) set to the larger speed beside them.

    Runs of up to ``max_length`` samples inside the recording are filled; a lost packet or two
    must not cut a stance in pieces too short to count (the foot would be released and slide);
    the larger neighbour never hides a turn that both sides show.
    """
    out = speed.copy()
    edges = np.diff(np.r_[0, (~np.isfinite(speed)).astype(np.int8), 0])
    for start, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        if 0 < start and end < len(speed) and end - start <= max_length:
            out[start:end] = max(speed[start - 1], speed[end])
    return out
