"""Flight and landings from the accelerometers: free fall of the trunk, impacts of the feet.

An accelerometer measures specific force ``f = R_world_sensor^T (a - g)``. While the body is in
the air nothing but gravity acts on it, so a unit near the centre of mass (the pelvis) reads
``|f|`` near 0: *free fall*. On the ground the same unit reads about ``|g|`` (walking stays
within a few m/s^2 of it), and a landing shows as a peak of ``|f|`` at the feet. So:

* a sample is *free* when the pelvis reads ``|f| < free_fall`` and no foot unit rests on the
  floor (``|f|`` near ``|g|`` while it does not turn), and no foot unit reports an impact;
* a flight is a run of free samples lasting at least ``min_duration``: shorter dips (the top of
  a bouncy step, a noise spike) are not flights;
* a flight ends at the first sample that is not free: the pelvis feels the floor again, or a
  foot hits it (``|f| > impact``); that sample is the *landing*.

The detector is causal with a fixed lag: whether sample ``k`` is airborne is known once sample
``k + lag`` has arrived, ``lag = round(min_duration * rate) - 1`` samples (50 ms at the
defaults, 2 samples at 60 Hz). :class:`FlightDetector` runs sample by sample (live);
:func:`detect_flight` runs it over whole arrays, so offline and live agree exactly.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

GRAVITY = 9.81  #: [m/s^2]


@dataclass(frozen=True)
class FlightThresholds:
    """What free fall, a resting foot and an impact mean.

    Attributes:
        free_fall: Pelvis ``|f|`` below which the body may be in the air [m/s^2]: about half
            its weight (walking stays above about 7; a flight reads about 0 plus what the legs'
            swing and the sensor's filters add).
        min_duration: Shortest flight [s]; it sets the detector's lag.
        rest_tolerance: A foot whose ``|f|`` is within this of ``|g|`` [m/s^2] ...
        rest_rate: ... and whose angular speed is below this [rad/s] rests on the floor.
        impact: Foot ``|f|`` above which a foot hits the floor [m/s^2].
    """

    free_fall: float = 5.0
    min_duration: float = 0.05
    rest_tolerance: float = 1.0
    rest_rate: float = 0.5
    impact: float = 25.0


@dataclass(frozen=True)
class FlightPhases:
    """Flight phases of a recording.

    Attributes:
        airborne: (N,) in the air.
        landings: Sample indices where a flight ended (the first sample on the ground).
        lag: Samples the causal decision waits for (see the module docstring).
    """

    airborne: np.ndarray
    landings: np.ndarray
    lag: int


def free_samples(acc_pelvis: np.ndarray | None, acc_feet: Mapping[str, np.ndarray],
                 gyr_feet: Mapping[str, np.ndarray | None] | None = None,
                 thresholds: FlightThresholds | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample evidence: (free, impact), each (N,) bool.

    Args:
        acc_pelvis: (N, 3) pelvis specific force in its sensor frame [m/s^2] (NaN where
            missing), or None when not recorded: then no sample is free.
        acc_feet: Foot segment -> (N, 3) its specific force [m/s^2] (NaN where missing).
        gyr_feet: Foot segment -> (N, 3) its angular rate [rad/s] or None (then a foot rests
            when its ``|f|`` alone says so).
        thresholds: See :class:`FlightThresholds`.

    Returns:
        ``free``: the pelvis in free fall, no foot resting, no impact (a missing pelvis sample
        is not free); ``impact``: some foot hits the floor.
    """
    th = thresholds or FlightThresholds()
    if acc_pelvis is None:
        n = len(next(iter(acc_feet.values()))) if acc_feet else 0
        return np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    free = np.linalg.norm(np.asarray(acc_pelvis, dtype=float), axis=1) < th.free_fall
    impact = np.zeros(len(free), dtype=bool)
    for foot, acc in acc_feet.items():
        magnitude = np.linalg.norm(np.asarray(acc, dtype=float), axis=1)
        resting = np.abs(magnitude - GRAVITY) < th.rest_tolerance
        gyr = None if gyr_feet is None else gyr_feet.get(foot)
        if gyr is not None:
            resting &= np.linalg.norm(np.asarray(gyr, dtype=float), axis=1) < th.rest_rate
        impact |= magnitude > th.impact
        free &= ~resting
    return free & ~impact, impact


class FlightDetector:
    """Sample-by-sample flight detection with a fixed lag (see the module docstring).

    Args:
        rate: Sample rate [Hz].
        thresholds: See :class:`FlightThresholds`.
    """

    def __init__(self, rate: float, thresholds: FlightThresholds | None = None) -> None:
        th = thresholds or FlightThresholds()
        self.min_samples = max(1, int(round(th.min_duration * rate)))
        #: samples between a sample's arrival and its decision
        self.lag = self.min_samples - 1
        self.reset()

    def reset(self) -> None:
        """No sample seen."""
        self._pending: deque[list[bool]] = deque()  # [airborne, landing] of undecided samples
        self._run = 0  # free samples in a row, up to the newest
        self._flying = False  # the newest samples belong to a confirmed flight

    def update(self, free: bool, impact: bool = False) -> tuple[bool, bool] | None:
        """Take the newest sample's evidence (:func:`free_samples`).

        Returns:
            ``(airborne, landing)`` of the sample ``lag`` samples back, None while fewer than
            ``lag + 1`` samples have arrived.
        """
        free = bool(free) and not impact
        landing = self._flying and not free
        self._run = self._run + 1 if free else 0
        self._flying = self._run >= self.min_samples
        self._pending.append([False, landing])
        if self._flying:  # the whole run is airborne: at most `lag` of it is still pending
            for entry in list(self._pending)[-min(self._run, len(self._pending)):]:
                entry[0] = True
        if len(self._pending) <= self.lag:
            return None
        airborne, landed = self._pending.popleft()
        return airborne, landed

    def flush(self) -> list[tuple[bool, bool]]:
        """The decisions still pending at the end of a recording, oldest first."""
        out = [(a, b) for a, b in self._pending]
        self._pending.clear()
        return out


def detect_flight(rate: float, acc_pelvis: np.ndarray | None, acc_feet: Mapping[str, np.ndarray],
                  gyr_feet: Mapping[str, np.ndarray | None] | None = None,
                  thresholds: FlightThresholds | None = None) -> FlightPhases:
    """Flight phases of a whole recording (the causal detector run over it).

    Args:
        rate: Sample rate [Hz].
        acc_pelvis: (N, 3) pelvis specific force [m/s^2] in the sensor frame, or None.
        acc_feet: Foot segment -> (N, 3) specific force [m/s^2].
        gyr_feet: Foot segment -> (N, 3) angular rate [rad/s] or None.
        thresholds: See :class:`FlightThresholds`.

    Returns:
        The :class:`FlightPhases`.
    """
    free, impact = free_samples(acc_pelvis, acc_feet, gyr_feet, thresholds)
    detector = FlightDetector(rate, thresholds)
    decisions = [d for f, i in zip(free, impact) if (d := detector.update(f, i)) is not None]
    decisions += detector.flush()
    airborne = np.array([a for a, _ in decisions], dtype=bool)
    landings = np.flatnonzero([b for _, b in decisions])
    return FlightPhases(airborne, landings, detector.lag)


def world_acceleration(R_world_sensor: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """``a_world`` (N, 3) [m/s^2] from an IMU's orientations (N, 3, 3) and specific force (N, 3).

    ``f = R_world_sensor^T (a - g)`` with ``g = (0, 0, -9.81)``, so ``a = R_world_sensor f + g``;
    NaN where either input is.
    """
    a = np.einsum("nij,nj->ni", np.asarray(R_world_sensor, dtype=float),
                  np.asarray(acc, dtype=float))
    a[:, 2] -= GRAVITY
    return a
