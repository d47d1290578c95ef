"""Flight and landings from the accelerometers: free fall of the trunk, impacts of the feet.

An accelerometer measures specific force ``f = R_world_sensor^T (a - g)``. While the body is in
the air nothing but gravity acts on it, so a unit near the centre of mass (the pelvis) reads
``|f|`` near 0: *free fall*. On the ground the same unit reads about ``|g|`` (walking stays
within a few m/s^2 of it), and a landing shows as a peak of ``|f|`` at the feet. So, with a
hysteresis:

* a sample is *free* when the pelvis reads ``|f| < free_fall`` while no foot unit rests on
  the floor (``|f|`` near ``|g|`` while it does not turn, for ``rest_duration``), *light* when
  the pelvis reads ``|f| < release``, no foot rests and no foot reports an impact (``|f| >
  impact`` while the pelvis is not free: a foot swung hard in the air peaks too);
* a flight is confirmed by a run of free samples lasting at least ``min_duration`` (shorter
  dips, the top of a bouncy step or a noise spike, are not flights); it also takes in the light
  samples just before that run (the take-off, where the sensor's own filtering rounds the
  drop of ``|f|``), up to ``extend`` seconds;
* it lasts while the samples stay light, and ends at the first that is not: the pelvis feels
  the floor again or a foot hits it. That sample is the *landing*.

The detector is causal with a fixed lag: whether sample ``k`` is airborne is known once sample
``k + lag`` has arrived, ``lag = round(min_duration * rate) - 1 + round(extend * rate)``
samples (5 samples, 83 ms, at 60 Hz with the defaults). :class:`FlightDetector` runs sample by
sample; :func:`detect_flight` runs it over whole arrays and
:class:`~ikfusion.imu.flight_stream.FlightStream` over IMU samples as they arrive (live), so
offline and live agree exactly on every decided sample. A live frame cannot wait for the lag:
it uses :attr:`FlightDetector.flying`, the flight as confirmed up to the newest sample.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

GRAVITY = 9.81  #: [m/s^2]


@dataclass(frozen=True)
class FlightThresholds:
    """What free fall, a resting foot and an impact mean.

    Attributes:
        free_fall: Pelvis ``|f|`` below which the body may be in the air [m/s^2]: about half
            its weight (walking stays above about 7; a flight reads about 0 plus what the legs'
            swing and the sensor's filters add).
        release: Pelvis ``|f|`` up to which a confirmed flight goes on [m/s^2] (hysteresis).
        min_duration: Shortest run of free samples that confirms a flight [s].
        extend: How far a confirmed flight reaches back over light samples [s].
        rest_tolerance: A foot whose ``|f|`` is within this of ``|g|`` [m/s^2] ...
        rest_rate: ... and whose angular speed is below this [rad/s] ...
        rest_duration: ... for this long up to the sample [s] rests on the floor (a foot in
            the air passes through such readings only for an instant).
        impact: Foot ``|f|`` above which a foot hits the floor [m/s^2] (about 4 g), when the
            pelvis is not in free fall at the same time.
    """

    free_fall: float = 5.0
    release: float = 8.0
    min_duration: float = 0.05
    extend: float = 0.05
    rest_tolerance: float = 1.0
    rest_rate: float = 0.5
    rest_duration: float = 0.1
    impact: float = 40.0


class FlightEvidence(NamedTuple):
    """Per-sample evidence (each (N,) bool): see the module docstring."""

    free: np.ndarray
    light: np.ndarray
    impact: np.ndarray


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


def flight_evidence(rate: float, acc_pelvis: np.ndarray | None,
                    acc_feet: Mapping[str, np.ndarray],
                    gyr_feet: Mapping[str, np.ndarray | None] | None = None,
                    thresholds: FlightThresholds | None = None) -> FlightEvidence:
    """Per-sample evidence of flight (causal: from the sample and those before it).

    Args:
        rate: Sample rate [Hz].
        acc_pelvis: (N, 3) pelvis specific force in its sensor frame [m/s^2] (NaN where
            missing: such a sample is not free), or None when not recorded: then none is.
        acc_feet: Foot segment -> (N, 3) its specific force [m/s^2] (NaN where missing).
        gyr_feet: Foot segment -> (N, 3) its angular rate [rad/s] or None (without it a foot
            is never taken as resting).
        thresholds: See :class:`FlightThresholds`.

    Returns:
        The :class:`FlightEvidence`.
    """
    th = thresholds or FlightThresholds()
    if acc_pelvis is None:
        n = len(next(iter(acc_feet.values()))) if acc_feet else 0
        none = np.zeros(n, dtype=bool)
        return FlightEvidence(none, none, none)
    pelvis = magnitude(np.asarray(acc_pelvis, dtype=float))
    impact = np.zeros(len(pelvis), dtype=bool)
    resting = np.zeros(len(pelvis), dtype=bool)
    for foot, acc in acc_feet.items():
        f_foot = magnitude(np.asarray(acc, dtype=float))
        impact |= f_foot > th.impact
        gyr = None if gyr_feet is None else gyr_feet.get(foot)
        if gyr is None:  # |f| near |g| alone is also a foot moving steadily through the air
            continue
        rests = foot_at_rest(f_foot, magnitude(np.asarray(gyr, dtype=float)), th)
        resting |= _held_for(rests, rest_samples(rate, th))
    return combined_evidence(pelvis, resting, impact, th)


def magnitude(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (3 components), summed in one fixed order.

    The batch (:func:`flight_evidence`) and the sample-by-sample twin
    (:class:`~ikfusion.imu.flight_stream.FlightStream`) both use it, so their thresholds see
    bit-identical values.
    """
    return np.asarray(np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]
                              + v[..., 2] * v[..., 2]))


def foot_at_rest(f_foot: np.ndarray, w_foot: np.ndarray, th: FlightThresholds) -> np.ndarray:
    """A foot's ``|f|`` [m/s^2] near ``|g|`` while it turns slower than ``rest_rate`` [rad/s].

    One sample's reading; it rests on the floor once this has held for :func:`rest_samples`.
    """
    return np.logical_and(np.abs(f_foot - GRAVITY) < th.rest_tolerance, w_foot < th.rest_rate)


def rest_samples(rate: float, th: FlightThresholds) -> int:
    """Samples a foot must read :func:`foot_at_rest` in a row to rest on the floor."""
    return max(1, int(round(th.rest_duration * rate)))


def combined_evidence(f_pelvis: np.ndarray, resting: np.ndarray, impact: np.ndarray,
                      th: FlightThresholds) -> FlightEvidence:
    """Free, light and impact from the pelvis ``|f|`` [m/s^2], resting feet and foot peaks.

    A foot's peak (``impact``: some foot read ``|f| > impact``) is a landing once the trunk
    also leaves free fall (a foot swung hard in the air peaks too, while the pelvis floats).
    """
    free = np.logical_and(f_pelvis < th.free_fall, np.logical_not(resting))
    impact = np.logical_and(impact, np.logical_not(free))
    light = np.logical_and(np.logical_and(f_pelvis < th.release, np.logical_not(resting)),
                           np.logical_not(impact))
    return FlightEvidence(np.asarray(free), np.asarray(light), np.asarray(impact))


def _held_for(mask: np.ndarray, n: int) -> np.ndarray:
    """Where ``mask`` has been True for the last ``n`` samples (the sample included).

    From the running count of True samples: the ``n`` samples up to ``k`` are all True when
    the count grew by ``n`` over them (integers, exact).
    """
    flags = np.asarray(mask, dtype=bool)
    if n <= 0:
        return np.ones(len(flags), dtype=bool)
    count = np.concatenate([[0], np.cumsum(flags, dtype=np.int64)])
    held = np.zeros(len(flags), dtype=bool)
    held[n - 1:] = count[n:] - count[:-n] == n
    return held


class FlightDetector:
    """Sample-by-sample flight detection with a fixed lag (see the module docstring).

    Args:
        rate: Sample rate [Hz].
        thresholds: See :class:`FlightThresholds`.
    """

    def __init__(self, rate: float, thresholds: FlightThresholds | None = None) -> None:
        th = thresholds or FlightThresholds()
        self.min_samples = max(1, int(round(th.min_duration * rate)))
        self.extend_samples = max(0, int(round(th.extend * rate)))
        #: samples between a sample's arrival and its decision
        self.lag = self.min_samples - 1 + self.extend_samples
        self.reset()

    def reset(self) -> None:
        """No sample seen."""
        # undecided samples, oldest first: [airborne, landing, light]
        self._pending: deque[list[bool]] = deque()
        self._run = 0  # free samples in a row, up to the newest
        self._flying = False  # the newest sample belongs to a confirmed flight

    def update(self, free: bool, light: bool, impact: bool = False) -> tuple[bool, bool] | None:
        """Take the newest sample's evidence (:func:`flight_evidence`).

        Returns:
            ``(airborne, landing)`` of the sample ``lag`` samples back, None while fewer than
            ``lag + 1`` samples have arrived.
        """
        light = bool(light and not impact)
        free = bool(free) and light
        self._run = self._run + 1 if free else 0
        entry = [False, False, light]
        self._pending.append(entry)
        if self._flying:
            if light:
                entry[0] = True
            else:
                entry[1] = True  # landing: the first sample back on the ground
                self._flying = False
        if not self._flying and self._run >= self.min_samples:
            self._flying = True
            self._confirm()
        if len(self._pending) <= self.lag:
            return None
        airborne, landing, _ = self._pending.popleft()
        return airborne, landing

    @property
    def flying(self) -> bool:
        """The newest sample belongs to a confirmed flight: known at once, without the lag.

        It is a part of the newest sample's final decision (what :meth:`update` returns
        ``lag`` samples later) that never changes: the landing is the same, only the start
        of a flight comes later, at the sample that confirms it (at most ``lag`` samples
        after the final start: the run of free samples and the take-off it reaches back over
        are decided only then).
        """
        return self._flying

    def _confirm(self) -> None:
        """Mark the run of free samples airborne, and the light samples just before it."""
        pending = list(self._pending)
        for entry in pending[len(pending) - self._run:]:
            entry[0] = True
        earlier = pending[:len(pending) - self._run]
        for entry in reversed(earlier[-self.extend_samples:] if self.extend_samples else []):
            if not entry[2] or entry[0]:
                break
            entry[0] = True

    def flush(self) -> list[tuple[bool, bool]]:
        """The decisions still pending at the end of a recording, oldest first."""
        out = [(a, b) for a, b, _ in self._pending]
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
    evidence = flight_evidence(rate, acc_pelvis, acc_feet, gyr_feet, thresholds)
    detector = FlightDetector(rate, thresholds)
    if not _held_for(evidence.free & evidence.light & ~evidence.impact,
                     detector.min_samples).any():
        # no run of free samples confirms a flight: every decision is (False, False)
        grounded = np.zeros(len(evidence.free), dtype=bool)
        return FlightPhases(grounded, np.flatnonzero(grounded), detector.lag)
    decisions = [d for f, li, i in zip(*evidence) if (d := detector.update(f, li, i))
                 is not None]
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
