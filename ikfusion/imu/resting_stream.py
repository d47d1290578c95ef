"""Rest of a hand or a knee from its IMU, sample by sample, from the past only (live, ``--causal``).

The rule of :func:`ikfusion.imu.resting.segment_resting` without its look-ahead, counted as
:class:`~ikfusion.imu.stance_stream.FootStillStream` counts a foot's calm: the segment rests
once its world acceleration (gravity removed) has stayed below ``max_acc`` for
``min_duration``; a short gap neither breaks nor extends a resting run.
"""

from __future__ import annotations

import numpy as np

from .flight import GRAVITY
from .resting import RestThresholds
from .stance import StanceThresholds
from .stance_stream import FootStillStream, vector_norm


class SegmentRestingStream(FootStillStream):
    """Causal resting/moving state of one hand or shin sensor.

    Args:
        rate: Nominal sample rate [Hz].
        thresholds: What resting means (:class:`~ikfusion.imu.resting.RestThresholds`).
    """

    def __init__(self, rate: float, thresholds: RestThresholds | None = None) -> None:
        th = thresholds or RestThresholds()
        # the foot's calm counter, run on |a_world| [m/s^2] instead of |omega| [rad/s]
        super().__init__(rate, StanceThresholds(th.max_acc, th.min_duration, th.window))

    def _speed(self, time_s: float, R: np.ndarray, acc: np.ndarray | None) -> float:
        """|a_world| [m/s^2] of this sample from its specific force ``acc`` (sensor frame)."""
        if acc is None:
            return float("nan")
        a = R @ np.asarray(acc, dtype=float)
        a[2] -= GRAVITY
        return vector_norm(a)
