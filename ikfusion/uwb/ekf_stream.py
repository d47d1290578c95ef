"""The tag filter of :mod:`ikfusion.uwb.ekf` stepped one IMU sample at a time, as samples arrive.

:func:`~ikfusion.uwb.ekf.run_unit_filter` filters a whole recording; :class:`UnitFilterStream`
runs the same filter (propagation, gates, resets, attitude aid, zero-velocity updates, output
offset) one sample at a time: :meth:`UnitFilterStream.sample` takes the unit's next IMU sample,
:meth:`UnitFilterStream.step` the tag's transmissions received in the interval that sample
closes, and returns the tag position and covariance at it. Nothing later is looked at: a lost
IMU sample is held from the last one (the offline filter interpolates across the gap), with the
process noise inflated over its intervals as offline.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .ekf import (
    EkfOptions,
    ImuSamples,
    UnitStart,
    UnitTrack,
    UnitTransmissions,
    UwbTotals,
    _seconds_without,
    _UnitFilter,
)


class UnitFilterStream(_UnitFilter):
    """One unit's filter fed sample by sample (see the module docstring).

    Args:
        p_world_readers: Reader positions, shape (M, 3) [m].
        reader_offsets: Reader clock offsets, shape (M,) [m].
        lever_sensor_tag: Sensor-to-tag lever arm in the sensor frame, shape (3,) [m].
        sigma: TOA noise [m] (``options.sigma`` overrides it).
        rate: IMU sample rate [Hz] (paces the attitude aid).
        options: Tuning (``smooth`` is ignored: a stream is causal).
    """

    def __init__(self, p_world_readers: np.ndarray, reader_offsets: np.ndarray,
                 lever_sensor_tag: np.ndarray, sigma: float, rate: float,
                 options: EkfOptions | None = None) -> None:
        opts = replace(options or EkfOptions(), smooth=False)
        m = len(reader_offsets)
        none = UnitTransmissions(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0),
                                 np.zeros((0, m)))
        # A window of two samples: the interval being propagated is always (0, 1).
        window = ImuSamples(np.full(2, np.nan), np.full((2, 3), np.nan),
                            np.full((2, 3), np.nan), np.full((2, 3, 3), np.nan))
        super().__init__(window, none, np.asarray(p_world_readers, dtype=float),
                         np.asarray(reader_offsets, dtype=float),
                         np.asarray(lever_sensor_tag, dtype=float),
                         opts.sigma if opts.sigma is not None else sigma, opts)
        self.acc, self.gyr = np.zeros((2, 3)), np.zeros((2, 3))
        self.missing = np.ones(2, dtype=bool)
        self.measured_time = np.full(2, -np.inf)
        self.attitude_every = max(1, round(float(rate) / opts.attitude_rate))
        self.steps = 0
        self.samples = 0
        self._tx: list[tuple[float, int, np.ndarray, np.ndarray, np.ndarray, bool]] = []
        #: (used at all, TOAs used, TOAs rejected) per transmission evaluated, for the fit
        self._counts: list[tuple[int, int, int]] = []
        #: Fills the fix of transmission ``i`` of the step's ``tx`` when the gate re-opens on
        #: it (fixes are costly and needed only then); None: the ``tx`` fixes are used as given.
        self.fill_fix: Callable[[UnitTransmissions, int], None] | None = None

    @property
    def started(self) -> bool:
        """The filter has a state (:meth:`start` was called)."""
        return self.x is not None

    @property
    def time(self) -> float:
        """Time of the last sample [s] (NaN before any)."""
        return float(self.imu.time[1])

    def sample(self, time_s: float, acc: np.ndarray | None, gyr: np.ndarray | None,
               R_world_sensor: np.ndarray | None) -> None:
        """The unit's next IMU sample (None or NaN: lost; held from the last one).

        Args:
            time_s: Sample time [s].
            acc: Specific force in the sensor frame (3,) [m/s^2].
            gyr: Angular rate in the sensor frame (3,) [rad/s].
            R_world_sensor: The IMU's own orientation (3, 3), the weak attitude aid.
        """
        imu = self.imu
        for rows in (imu.time, self.acc, self.gyr, self.missing, self.measured_time,
                     imu.R_world_sensor_aid):
            assert rows is not None
            rows[0] = rows[1]
        imu.time[1] = time_s
        good = (acc is not None and gyr is not None and np.isfinite(acc).all()
                and np.isfinite(gyr).all())
        if good:
            assert acc is not None and gyr is not None
            self.acc[1], self.gyr[1] = acc, gyr
        self.missing[1] = not good
        if good:
            self.measured_time[1] = time_s
        aid = imu.R_world_sensor_aid
        assert aid is not None
        aid[1] = R_world_sensor if R_world_sensor is not None else np.nan
        self.samples += 1

    def start(self, start: UnitStart) -> tuple[np.ndarray, np.ndarray]:
        """Start the filter at the last sample from ``start`` (its time at or before it).

        Returns:
            The tag position (3,) [m] and its covariance (3, 3) [m^2] at that sample.
        """
        self._initialise(start, 1)
        self.steps = 0
        return self._output(0.0)

    def step(self, tx: UnitTransmissions, still: bool) -> tuple[np.ndarray, np.ndarray]:
        """Propagate to the last sample with the transmissions received since the one before.

        Args:
            tx: The tag's transmissions inside the interval, in time order (their ``fix_*``
                used when the gate re-opens).
            still: The unit stands still at the last sample (a foot in stance).

        Returns:
            The tag position (3,) [m] and its covariance (3, 3) [m^2] at the last sample.
        """
        time = self.imu.time
        m = self.readers.shape[0]
        self.tx = tx
        self.used = np.zeros((len(tx), m), dtype=bool)
        self.rejected = np.zeros((len(tx), m), dtype=bool)
        self.reset = np.zeros(len(tx), dtype=bool)
        self._interval(0, float(time[0]), float(time[1]), 0)
        self.steps += 1
        if self.steps % self.attitude_every == 0:
            self._attitude_update(1)
        if still:
            self._zero_velocity_update()
        for i in range(len(tx)):
            used, rejected = self.used[i].copy(), self.rejected[i].copy()
            self._tx.append((float(tx.time[i]), int(tx.seq[i]), np.isfinite(tx.toa[i]),
                             used, rejected, bool(self.reset[i])))
            toas_used = int(np.count_nonzero(used))
            self._counts.append((int(toas_used > 0), toas_used, int(np.count_nonzero(rejected))))
        return self._output(float(time[1] - time[0]))

    def _reopen(self, i: int) -> None:
        if self.fill_fix is not None:
            self.fill_fix(self.tx, i)
        super()._reopen(i)

    def _output(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        p, cov, quat = np.full((1, 3), np.nan), np.full((1, 3, 3), np.nan), np.full((1, 4), 0.0)
        self._record(0, p, cov, quat, dt)
        return p[0], cov[0]

    @property
    def evaluated(self) -> int:
        """Transmissions evaluated so far."""
        return len(self._counts)

    def last_counts(self, n: int) -> tuple[int, int, int, int]:
        """Counts of the last ``n`` transmissions evaluated (cheap to call every frame).

        Returns:
            How many, how many used, TOAs used and TOAs rejected.
        """
        rows = self._counts[-n:]
        return (len(rows), sum(r[0] for r in rows), sum(r[1] for r in rows),
                sum(r[2] for r in rows))

    def track(self, time: np.ndarray, p_world_tag: np.ndarray, cov: np.ndarray) -> UnitTrack:
        """The :class:`~ikfusion.uwb.ekf.UnitTrack` of the stream so far.

        Args:
            time: Frame times (N,) [s].
            p_world_tag: The tag positions the stream returned at them (N, 3) [m].
            cov: Their covariances (N, 3, 3) [m^2].
        """
        m = self.readers.shape[0]
        rows = self._tx
        tx_time = np.array([r[0] for r in rows], dtype=float)
        seq = np.array([r[1] for r in rows], dtype=np.int64)

        def stack(j: int) -> np.ndarray:
            return np.array([r[j] for r in rows], dtype=bool).reshape(len(rows), m)

        heard, used, rejected = stack(2), stack(3), stack(4)
        reset = np.array([r[5] for r in rows], dtype=bool)
        used_tx = used.any(axis=1)
        totals = UwbTotals(int(heard.any(axis=1).sum()), int(used_tx.sum()), int(heard.sum()),
                           int(used.sum()), int(rejected.sum()), int(reset.sum()),
                           _seconds_without(time, tx_time[used_tx], 0.5) if len(time) else 0.0)
        quat = np.full((len(time), 4), math.nan)
        return UnitTrack(time, p_world_tag, cov, quat, tx_time, seq, used, rejected, heard,
                         reset, totals)
