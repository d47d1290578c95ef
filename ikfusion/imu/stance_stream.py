"""Stance of a foot from its IMU, sample by sample, from the past only (live and ``--causal``).

The same rule as :func:`ikfusion.imu.stance.foot_still` without its look-ahead: the angular
speed of a sample is its gyroscope's when recorded, else the turn from the previous received
sample divided by the time between them; the foot is *calm* while the largest speed of the last
``window`` seconds stays below ``max_rate`` (and, when the accelerometer is recorded, the largest
acceleration without gravity below ``max_acceleration``), and *still* once it has been calm for
``min_duration`` (a stance is therefore recognised ``min_duration`` after it starts, the lag of
this detector). A gap of up to ``min_duration`` neither breaks nor extends a calm run (a lost
packet or two must not release a planted foot); a longer gap starts counting afresh.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from ..rotations import log_so3
from .flight import world_acceleration
from .stance import StanceThresholds


class FootStillStream:
    """Causal still/moving state of one foot sensor.

    Args:
        rate: Nominal sample rate [Hz] (for the window and minimum run in samples).
        thresholds: What still means (:class:`~ikfusion.imu.stance.StanceThresholds`).
    """

    def __init__(self, rate: float, thresholds: StanceThresholds | None = None) -> None:
        th = thresholds or StanceThresholds()
        self.max_rate = th.max_rate
        self.max_acceleration = th.max_acceleration
        self.min_length = max(1, int(round(th.min_duration * rate)))
        width = max(1, int(round(th.window * rate)))
        self._speeds: deque[float] = deque(maxlen=width)
        self._accelerations: deque[float] = deque(maxlen=width)
        self._calm_run = 0
        self._missing = 0
        self._last: tuple[float, np.ndarray] | None = None  # time [s], R_world_sensor

    def update(self, time_s: float, R_world_sensor: np.ndarray | None,
               gyr: np.ndarray | None = None, acc: np.ndarray | None = None) -> float:
        """The state at one sample: 1.0 still, 0.0 moving, NaN unknown (no valid sample).

        Args:
            time_s: Sample time [s].
            R_world_sensor: (3, 3) the foot sensor's orientation, or None when the sample is
                missing or invalid.
            gyr: (3,) its angular rate [rad/s] in the sensor frame, when recorded.
            acc: (3,) its specific force [m/s^2] in the sensor frame, when recorded.
        """
        if R_world_sensor is None:
            self._missing += 1
            if self._missing > self.min_length:
                self._calm_run = 0
                self._speeds.clear()
                self._accelerations.clear()
            return float("nan")
        speed = self._speed(time_s, R_world_sensor, gyr)
        self._last = (time_s, R_world_sensor)
        self._missing = 0
        if not math.isfinite(speed):
            return float("nan")
        self._speeds.append(speed)
        calm = max(self._speeds) < self.max_rate
        if acc is not None:
            size = vector_norm(world_acceleration(R_world_sensor[None],
                                            np.asarray(acc, dtype=float)[None])[0])
            if math.isfinite(size):  # NaN or inf wherever the sample's is
                self._accelerations.append(size)
        if self._accelerations:
            calm &= max(self._accelerations) < self.max_acceleration
        self._calm_run = self._calm_run + 1 if calm else 0
        return 1.0 if self._calm_run >= self.min_length else 0.0

    def _speed(self, time_s: float, R: np.ndarray, gyr: np.ndarray | None) -> float:
        """|omega| [rad/s] of this sample (gyroscope, else the turn since the last sample)."""
        if gyr is not None:
            return vector_norm(np.asarray(gyr, dtype=float))
        if self._last is None or time_s <= self._last[0]:
            return float("nan")
        t0, R0 = self._last
        return vector_norm(log_so3(R0.T @ R)) / (time_s - t0)


def vector_norm(v: np.ndarray) -> float:
    """|v| of a (3,) float vector, as ``np.linalg.norm`` computes it (without its checks)."""
    return math.sqrt(float(v.dot(v)))
