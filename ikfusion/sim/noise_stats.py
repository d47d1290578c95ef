"""How much a reported orientation turns between samples: still periods, gyro agreement.

The measures that compare the simulator's orientation errors (:class:`ikfusion.sim.imu.ImuNoise`)
with real sensors' output (MT Manager exports, MVNX sensor orientations):

* :func:`turn_steps_deg`: the angle the orientation turns from one sample to the next;
* :func:`turn_speed_deg_s`: the turn rate over a short centred window, to find still and slow
  periods of the motion itself (the window averages the per-sample jitter away);
* :func:`beyond_gyro_deg`: how far each sample-to-sample turn differs from what the sensor's own
  gyroscope says: a fusion filter's correction, the part of the error that changes per sample.
"""

from __future__ import annotations

import numpy as np

from ..rotations import log_so3


def _relative_turns(R_world_sensor: np.ndarray, lag: int) -> np.ndarray:
    """Rotation vectors ``log(R_k^T R_{k+lag})`` (N - lag, 3) in the sensor frame [rad]."""
    R = np.asarray(R_world_sensor, dtype=float)
    return log_so3(np.swapaxes(R[:-lag], -1, -2) @ R[lag:])


def turn_steps_deg(R_world_sensor: np.ndarray) -> np.ndarray:
    """Angle between consecutive orientations (N - 1,) [deg]; NaN where a sample is missing.

    Args:
        R_world_sensor: (N, 3, 3) reported orientations, any world frame.
    """
    if len(R_world_sensor) < 2:
        return np.empty(0)
    return np.degrees(np.linalg.norm(_relative_turns(R_world_sensor, 1), axis=-1))


def turn_speed_deg_s(R_world_sensor: np.ndarray, rate: float, window_s: float = 0.1) -> np.ndarray:
    """Turn rate over a centred window (N,) [deg/s]: ``angle(R_{k-h}, R_{k+h}) / (2 h dt)``.

    Args:
        R_world_sensor: (N, 3, 3) orientations.
        rate: Sample rate [Hz].
        window_s: Window length [s] (at least two samples).

    Returns:
        The speed per sample, NaN within half a window of the ends and around missing samples.
    """
    n = len(R_world_sensor)
    half = max(1, round(window_s * rate / 2))
    speed = np.full(n, np.nan)
    if n > 2 * half:
        turn = np.degrees(np.linalg.norm(_relative_turns(R_world_sensor, 2 * half), axis=-1))
        speed[half:n - half] = turn * rate / (2 * half)
    return speed


def beyond_gyro_deg(R_world_sensor: np.ndarray, gyr: np.ndarray, rate: float) -> np.ndarray:
    """Per-sample turn minus the gyroscope's, ``log(R_k^T R_{k+1}) - gyr_{k+1} dt`` (N-1, 3) [deg].

    An MTw-class filter propagates its orientation with the rate of the new sample (MT Manager
    exports of ``../shared/data/xsens`` agree best with ``gyr_{k+1}``), then corrects it through
    gravity and the magnetometer: this difference is that correction plus the gyroscope bias the
    filter removes (a constant; subtract the mean to drop it).

    Args:
        R_world_sensor: (N, 3, 3) reported orientations.
        gyr: (N, 3) angular rate in the sensor frame [rad/s].
        rate: Sample rate [Hz].
    """
    if len(R_world_sensor) < 2:
        return np.empty((0, 3))
    return np.degrees(_relative_turns(R_world_sensor, 1) - np.asarray(gyr)[1:] / rate)


def rms(values: np.ndarray, axis: int | None = None) -> float:
    """Root mean square over the finite entries (of the vector norms when ``axis`` is given)."""
    x = np.asarray(values, dtype=float)
    if axis is not None:
        x = np.linalg.norm(x, axis=axis)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")
