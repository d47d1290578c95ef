"""Still windows: where every sensor is at rest (for calibration), found or checked.

Two measures, per sensor and window:

* the orientation spread: RMS angle [deg] between the window's orientations and their mean,
  from the sign-aligned quaternion mean ``m`` (``RMS angle ~= 2 sqrt(1 - |m|^2)`` for small
  spreads), computed for every window at once with cumulative sums;
* the mean angular speed [rad/s] from the gyroscope, when it was recorded.

A window is still when no sensor exceeds either threshold. :func:`find_still_window` returns the
stillest window of 2 s (else 1.5 s, else 1 s) in the first still stretch of the recording.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..rotations import (
    FEW_MATRICES,
    continuous_quaternions,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
)


@dataclass(frozen=True)
class StillThresholds:
    """Largest motion of a still sensor.

    Attributes:
        spread_deg: RMS orientation spread about the window mean [deg].
        gyr: Mean angular speed [rad/s] (used when gyroscopes were recorded).
    """

    spread_deg: float = 3.0
    gyr: float = 0.25


def aligned_quaternions(R_world_sensor: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions (w, x, y, z) with continuous signs; NaN where the input is NaN.

    Consecutive quaternions are made to lie in the same hemisphere, comparing each one with the
    last finite one before it.
    """
    q = np.full((len(R_world_sensor), 4), np.nan)
    good = np.isfinite(R_world_sensor).all(axis=(1, 2))
    if good.any():
        q[good] = matrix_to_quat_wxyz(R_world_sensor[good])
    return continuous_quaternions(q)


def _window_sums(values: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Sums of finite rows and counts of finite rows over every window of ``width`` rows."""
    finite = np.isfinite(values).all(axis=1) if values.ndim == 2 else np.isfinite(values)
    filled = np.where(finite[:, None] if values.ndim == 2 else finite, values, 0.0)
    csum = np.concatenate([np.zeros((1,) + filled.shape[1:]), np.cumsum(filled, axis=0)])
    ccount = np.concatenate([[0], np.cumsum(finite)])
    return csum[width:] - csum[:-width], ccount[width:] - ccount[:-width]


def spread_per_window(R_world_sensor: np.ndarray, width: int) -> np.ndarray:
    """RMS orientation spread [deg] of every window of ``width`` samples (inf if mostly NaN)."""
    return _spread_of_quaternions(aligned_quaternions(R_world_sensor), width)


def _spread_of_quaternions(q: np.ndarray, width: int) -> np.ndarray:
    """:func:`spread_per_window` of the orientations whose :func:`aligned_quaternions` are ``q``.

    Every step works sample by sample or accumulates in order (the quaternions, their signs,
    the running sums), so the windows of a prefix ``q[:m]`` are the first ``m - width + 1``
    windows of ``q``, to the bit: the quaternions of the longest prefix serve every width.
    """
    sums, counts = _window_sums(q, width)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums / counts[:, None]
        norm2 = np.einsum("ij,ij->i", mean, mean)
        spread = np.degrees(2.0 * np.sqrt(np.clip(1.0 - norm2, 0.0, None)))
    spread[counts < 0.8 * width] = np.inf
    return spread


def gyr_per_window(gyr: np.ndarray, width: int) -> np.ndarray:
    """Mean angular speed [rad/s] of every window of ``width`` samples (inf if mostly NaN)."""
    speed = np.linalg.norm(gyr, axis=1)
    sums, counts = _window_sums(speed, width)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums / counts
    mean[counts < 0.8 * width] = np.inf
    return mean


def window_motion(R_world_sensor: Mapping[str, np.ndarray], window: tuple[int, int],
                  gyr: Mapping[str, np.ndarray | None] | None = None
                  ) -> dict[str, tuple[float, float | None]]:
    """Per sensor: (orientation spread [deg], mean angular speed [rad/s] or None) in a window."""
    start, end = window
    out: dict[str, tuple[float, float | None]] = {}
    for name, R in R_world_sensor.items():
        spread = float(spread_per_window(R[start:end], end - start)[0])
        g = None if gyr is None else gyr.get(name)
        speed = None if g is None else float(gyr_per_window(g[start:end], end - start)[0])
        out[name] = (spread, speed)
    return out


def moved_sensors(motion: Mapping[str, tuple[float, float | None]],
                  thresholds: StillThresholds) -> list[str]:
    """Readable list of the sensors above a threshold, e.g. ``RightLowerLeg (12.3 deg)``."""
    moved = []
    for name, (spread, speed) in motion.items():
        parts = []
        if not np.isfinite(spread):
            parts.append("no data")
        elif spread > thresholds.spread_deg:
            parts.append(f"{spread:.1f} deg RMS")
        if speed is not None and np.isfinite(speed) and speed > thresholds.gyr:
            parts.append(f"{np.degrees(speed):.0f} deg/s")
        if parts:
            moved.append(f"{name} ({', '.join(parts)})")
    return moved


def check_still(R_world_sensor: Mapping[str, np.ndarray], window: tuple[int, int], rate: float,
                gyr: Mapping[str, np.ndarray | None] | None = None,
                thresholds: StillThresholds | None = None) -> dict[str, float]:
    """Check that every sensor is still in a window.

    Returns:
        Sensor -> orientation spread [deg].

    Raises:
        InputError: Naming the sensors that moved (and by how much) or the bad window.
    """
    limits = thresholds or StillThresholds()
    n = min(len(R) for R in R_world_sensor.values())
    start, end = window
    if not 0 <= start < end <= n or end - start < 2:
        raise InputError(f"the calibration window {start / rate:.2f}-{end / rate:.2f} s is not "
                         f"inside the recording (0-{n / rate:.2f} s) or is shorter than two "
                         "samples", field="calibrate")
    motion = window_motion(R_world_sensor, window, gyr)
    moved = moved_sensors(motion, limits)
    if moved:
        raise InputError(f"the calibration window {start / rate:.2f}-{end / rate:.2f} s is not "
                         f"still: {', '.join(moved)} (a still sensor stays under "
                         f"{limits.spread_deg:g} deg RMS and {np.degrees(limits.gyr):.0f} "
                         "deg/s); give a window where the subject stands still",
                         field="calibrate")
    return {name: m[0] for name, m in motion.items()}


def find_still_window(R_world_sensor: Mapping[str, np.ndarray], rate: float,
                      gyr: Mapping[str, np.ndarray | None] | None = None,
                      seconds: tuple[float, ...] = (2.0, 1.5, 1.0), search: float = 10.0,
                      thresholds: StillThresholds | None = None) -> tuple[int, int]:
    """The still window at the start of a recording (the calibration pose).

    Every window of each length in ``seconds`` that starts within the first ``search`` seconds
    is scored by its most moving sensor (spread and angular speed, each divided by its
    threshold; <= 1 is still). The first still stretch of the recording is the pose: the
    longest length that fits in it wins, with its stillest window there.

    Args:
        R_world_sensor: Sensor (or segment) -> (N, 3, 3) orientations.
        rate: Sample rate [Hz].
        gyr: Sensor -> (N, 3) angular rate [rad/s] (or None), when recorded.
        seconds: Window lengths to try [s].
        search: Windows start within this many seconds of the start [s].
        thresholds: What still means.

    Returns:
        (start, end) sample indices.

    Raises:
        InputError: No still window: naming the sensors that moved in the stillest one.
    """
    limits = thresholds or StillThresholds()
    n = min(len(R) for R in R_world_sensor.values())
    windows = {}  # width -> windows starting at 0 .. starts - 1
    for length in seconds:
        width = max(2, int(round(length * rate)))
        if width <= n:
            windows[width] = min(n - width + 1, max(1, int(round(search * rate)) + 1))
    # the quaternions of the samples any window covers, converted once for every width
    covered = max((starts + width - 1 for width, starts in windows.items()), default=0)
    shared = {name: aligned_quaternions(R[:covered]) for name, R in R_world_sensor.items()}
    scores = {}
    for width, starts in windows.items():
        quats = {name: _prefix_quaternions(R, shared[name], starts + width - 1)
                 for name, R in R_world_sensor.items()}
        scores[width] = _window_scores(quats, gyr, width, starts, limits)
    if not scores:
        raise InputError(f"the recording ({n} samples) is shorter than a "
                         f"{min(seconds):g} s calibration window", field="calibrate")
    stretch = _first_still_stretch(scores)
    if stretch is not None:
        for width in sorted(scores, reverse=True):
            score = scores[width][stretch[0]:max(stretch[0], stretch[1] - width + 1)]
            if len(score) and score.min() <= 1.0:
                k = stretch[0] + int(np.argmin(score))
                return k, k + width
    width = min(scores)
    k = int(np.argmin(scores[width]))
    window = (k, k + width)
    moved = moved_sensors(window_motion(R_world_sensor, window, gyr), limits)
    raise InputError(f"no still window of {min(seconds):g} s in the first {search:g} s: in the "
                     f"stillest one ({window[0] / rate:.2f}-{window[1] / rate:.2f} s) "
                     f"{', '.join(moved) or 'the sensors'} moved; stand still at the start or "
                     "give the window (--calibrate T0:T1)", field="calibrate")


def _prefix_quaternions(R_world_sensor: np.ndarray, shared: np.ndarray,
                        needed: int) -> np.ndarray:
    """``aligned_quaternions(R_world_sensor[:needed])`` from those of a longer prefix.

    ``shared`` is :func:`aligned_quaternions` of the first ``len(shared) >= needed`` samples;
    its first ``needed`` rows are the same, to the bit (:func:`_spread_of_quaternions`),
    unless the shorter prefix has few enough finite samples for
    :func:`~ikfusion.rotations.matrix_to_quat_wxyz` to convert them matrix by matrix (another
    arithmetic) and the longer one not: then it is converted on its own, as before.
    """
    finite = np.isfinite(R_world_sensor[:len(shared)]).all(axis=(1, 2))
    if int(finite[:needed].sum()) <= FEW_MATRICES < int(finite.sum()):
        return aligned_quaternions(R_world_sensor[:needed])
    return shared[:needed]


def _window_scores(quats: Mapping[str, np.ndarray],
                   gyr: Mapping[str, np.ndarray | None] | None, width: int, starts: int,
                   limits: StillThresholds) -> np.ndarray:
    """Scores of the windows of ``width`` samples starting at 0 .. ``starts - 1``.

    A window's score is its most moving sensor's spread and angular speed, each divided by its
    threshold: <= 1 is still. ``quats``: sensor -> :func:`aligned_quaternions` of its first
    samples (at least ``starts + width - 1``).
    """
    score = np.zeros(starts)
    for name, q in quats.items():
        score = np.maximum(score, _spread_of_quaternions(q[:starts + width - 1], width)[:starts]
                           / limits.spread_deg)
        g = None if gyr is None else gyr.get(name)
        if g is not None and np.isfinite(g).any():
            speed = gyr_per_window(g[:starts + width - 1], width)[:starts]
            score = np.maximum(score, np.where(np.isfinite(speed), speed, 0.0) / limits.gyr)
    return score


def _first_still_stretch(scores: Mapping[int, np.ndarray]) -> tuple[int, int] | None:
    """Samples ``(start, end)`` of the first still stretch, None when nothing is still.

    The N-pose is the first still moment of a recording; a later pause (standing in a stride
    between walks, a rest between trials) can be stiller but is not the calibration pose. The
    stretch begins with the earliest still window of any length and ends where windows of that
    length stop being still.
    """
    first: tuple[int, int] | None = None
    for width, score in scores.items():
        still = np.flatnonzero(score <= 1.0)
        if len(still) and (first is None or still[0] < first[0]):
            first = (int(still[0]), width)
    if first is None:
        return None
    start, width = first
    moving = np.flatnonzero(scores[width][start:] > 1.0)
    run = int(moving[0]) if len(moving) else len(scores[width]) - start
    return start, start + run - 1 + width


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """Quaternion (chordal L2) mean (3, 3) of rotations (k, 3, 3); NaN entries are ignored.

    The mean quaternion is the dominant eigenvector of ``sum q q^T``, which does not depend on
    the signs of the quaternions.

    Raises:
        InputError: No finite rotation.
    """
    good = np.isfinite(R).all(axis=(1, 2))
    if not good.any():
        raise InputError("no finite orientation to average", field="calibrate")
    q = matrix_to_quat_wxyz(R[good])
    _, vectors = np.linalg.eigh(q.T @ q)
    return quat_wxyz_to_matrix(vectors[:, -1])
