"""Flight phases sample by sample, as IMU samples arrive (live and ``solve --causal``).

The streaming twin of :func:`ikfusion.imu.flight.detect_flight`: the same evidence per sample
(:func:`~ikfusion.imu.flight.combined_evidence`, with a run counter per foot for how long it
has rested) fed to the same :class:`~ikfusion.imu.flight.FlightDetector`, so every sample's
lagged decision equals the batch one. A frame solved as it arrives cannot wait the detector's
lag (83 ms at 60 Hz): it takes :attr:`FlightStream.flying`, the flight as confirmed up to that
sample (never airborne where the final decision is not; a flight starts up to ``lag`` samples
late and ends on the same sample).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .flight import (
    FlightDetector,
    FlightThresholds,
    combined_evidence,
    foot_at_rest,
    magnitude,
    rest_samples,
)

#: Foot segments whose units tell a resting foot and a landing.
FEET = ("LeftFoot", "RightFoot")

_MISSING = np.full(3, np.nan)


class FlightStream:
    """Flight from one sample of the pelvis and feet units at a time.

    Args:
        rate: Sample rate [Hz].
        thresholds: See :class:`~ikfusion.imu.flight.FlightThresholds`.
    """

    def __init__(self, rate: float, thresholds: FlightThresholds | None = None) -> None:
        self.thresholds = thresholds or FlightThresholds()
        self.detector = FlightDetector(rate, self.thresholds)
        self._rest_samples = rest_samples(rate, self.thresholds)
        self._rested = {foot: 0 for foot in FEET}  # samples in a row each foot read at rest

    @property
    def lag(self) -> int:
        """Samples between a sample's arrival and its final decision."""
        return self.detector.lag

    @property
    def flying(self) -> bool:
        """The newest sample is in a confirmed flight (:attr:`FlightDetector.flying`)."""
        return self.detector.flying

    def update(self, acc_pelvis: np.ndarray | None,
               acc_feet: Mapping[str, np.ndarray | None],
               gyr_feet: Mapping[str, np.ndarray | None]) -> tuple[bool, bool] | None:
        """Take the newest sample of each unit (None: missing or invalid, as a NaN sample).

        Args:
            acc_pelvis: (3,) pelvis specific force in its sensor frame [m/s^2].
            acc_feet: Foot segment -> (3,) its specific force [m/s^2].
            gyr_feet: Foot segment -> (3,) its angular rate [rad/s].

        Returns:
            ``(airborne, landing)`` of the sample ``lag`` samples back (as
            :func:`~ikfusion.imu.flight.detect_flight` decides it), None while fewer than
            ``lag + 1`` samples have arrived.
        """
        th = self.thresholds
        impact = resting = False
        for foot in FEET:
            acc, gyr = acc_feet.get(foot), gyr_feet.get(foot)
            f_foot = magnitude(_vector(acc))
            impact = impact or bool(f_foot > th.impact)
            at_rest = bool(foot_at_rest(f_foot, magnitude(_vector(gyr)), th))
            self._rested[foot] = self._rested[foot] + 1 if at_rest else 0
            resting = resting or self._rested[foot] >= self._rest_samples
        if acc_pelvis is None:
            f_pelvis = magnitude(_MISSING)
        else:
            f_pelvis = magnitude(np.asarray(acc_pelvis, dtype=float))
        free, light, impact_sample = combined_evidence(f_pelvis, np.asarray(resting),
                                                       np.asarray(impact), th)
        return self.detector.update(bool(free), bool(light), bool(impact_sample))

    def flush(self) -> list[tuple[bool, bool]]:
        """The decisions still pending at the end of a stream, oldest first."""
        return self.detector.flush()


def _vector(value: np.ndarray | None) -> np.ndarray:
    """``value`` as a float (3,) vector; NaN when missing."""
    return _MISSING if value is None else np.asarray(value, dtype=float)
