"""Tightly coupled IMU + UWB error-state EKF for one unit (an IMU carrying a UWB tag).

The filter runs at the IMU rate: each IMU interval propagates the nominal state with the
trapezoidal mean of the two samples' specific force [m/s^2] and angular rate [rad/s] (sensor
frame) and the error covariance with the linearised dynamics (:mod:`ikfusion.uwb.ekf_model`).
A transmission is processed at its own time inside the interval (the state is propagated to
it, updated, then propagated on), from its raw times of arrival [m], with no multilateration:

- each TOA's innovation ``nu = toa - predicted`` is normalised by its predicted standard
  deviation; a TOA later than ``gate_late`` sigma is rejected (NLOS only delays), one earlier
  than ``gate_early`` sigma too (a gross error); the others update the state together;
- when ``reset_after`` transmissions in a row heard by at least 3 readers have most of their
  TOAs rejected (the filter has diverged), or when UWB returns after ``reacquire_after``
  seconds without a used transmission, the gate re-opens (as flight-controller EKFs do): the
  position and transmit time are reset to that transmission's own fix (when one is given; its
  covariance becomes theirs, velocity, tilt and accelerometer bias get their initial
  uncertainty) or, without a fix, their covariance is inflated; the transmission is then
  tested again;
- the orientation reported by the IMU's own fusion (``R_world_sensor_aid``) is a weak attitude
  measurement at about 10 Hz, and an optional tag height [m] a pseudo-measurement at each
  transmission;
- while the unit is known to stand still (a foot in stance, ``still``), a zero-velocity
  update at every sample (ZUPT) keeps its velocity, and so its position, from drifting when
  few or no readers hear it.

The reported tag position follows the filter through an output offset that absorbs every
correction and decays (time constant ``output_time_constant``, at most
``max_output_speed`` per second), so a large correction, e.g. when UWB returns after a coast,
is spread over frames instead of jumping; the reported covariance adds that offset's outer
product.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..rotations import log_so3
from .ekf_model import (
    ATT,
    BACC,
    BGYR,
    CLOCK,
    CLOCK_RATE,
    N_ERROR,
    POS,
    VEL,
    NominalState,
    fill_transition,
    inject_error,
    matrix_to_quat,
    new_transition,
    predict_toa_unit,
    process_noise_diagonal,
    propagate_nominal,
    tag_position,
    tag_position_jacobian,
)
from .smoother import SmootherLog

#: Variance inflation of the process noise over an interval whose IMU sample is missing.
_MISSING_SAMPLE_INFLATION = 25.0


@dataclass(frozen=True)
class EkfOptions:
    """Tuning of :func:`run_unit_filter` (noise densities are continuous-time).

    Attributes:
        sigma: TOA noise [m]; None takes the constellation's ``sigma``.
        acc_noise: Accelerometer noise density incl. model error [m/s^2/sqrt(Hz)].
        gyr_noise: Gyroscope noise density [rad/s/sqrt(Hz)].
        acc_bias_walk: Accelerometer bias random walk [m/s^2/sqrt(s)].
        gyr_bias_walk: Gyroscope bias random walk [rad/s/sqrt(s)].
        clock_noise: Transmit-time random walk [m/sqrt(s)].
        clock_rate_walk: Transmit-time rate random walk [m/s/sqrt(s)].
        gate_late: One-sided gate on late TOAs [sigma of the innovation].
        gate_early: Gate on early TOAs (gross errors only) [sigma].
        reset_after: Transmissions in a row with most TOAs rejected before the gate re-opens.
        reacquire_after: A transmission heard by 4+ readers after this long without a used
            one re-opens the gate too (UWB returning after a coast) [s].
        attitude_sigma_deg: Tilt noise of the IMU's own orientation used as a weak aid [deg];
            None disables the aid.
        attitude_heading_sigma_deg: Heading noise of that aid [deg] (magnetic heading wanders).
        attitude_rate: Rate of the attitude aid [Hz].
        height_sigma: Noise of the tag-height pseudo-measurement [m].
        initial_velocity_sigma: Initial velocity uncertainty [m/s].
        initial_attitude_sigma_deg: Initial attitude uncertainty [deg].
        initial_acc_bias_sigma: Initial accelerometer bias uncertainty [m/s^2].
        initial_gyr_bias_sigma: Initial gyroscope bias uncertainty [rad/s].
        output_time_constant: Decay time of the output offset [s].
        max_output_speed: Largest speed at which the output offset decays [m/s].
        zupt_sigma: Velocity noise of a zero-velocity update [m/s] (a foot rolls a little).
        missing_acc_noise: Over an interval of a silent sensor (more than ``fill_trusted_s``
            since its last sample) the specific force is a fill, not a measurement: the
            velocity noise density is at least this, the unit's unknown motion (a limb's
            ~10 m/s^2 RMS over ~25 Hz) [m/s^2/sqrt(Hz)]. With the sensor's own noise a foot's
            track coasted metres off in a 2 s dropout, every TOA was gated out as NLOS, and the
            smoother spread it back.
        missing_gyr_noise: ... and the attitude noise density at least this (~2.5 rad/s RMS)
            [rad/s/sqrt(Hz)].
        fill_trusted_s: Samples missing for up to this long (a lost packet or two) are filled
            faithfully (interpolated offline, body motion is slower than ~10 Hz): their
            interval keeps the sensor's noise, inflated [s].
        smooth: Also run the Rauch-Tung-Striebel pass backward (:mod:`ikfusion.uwb.smoother`):
            every instant then uses the whole recording; False gives the causal filter.
    """

    sigma: float | None = None
    acc_noise: float = 0.01
    gyr_noise: float = 0.001
    acc_bias_walk: float = 0.002
    gyr_bias_walk: float = 1e-4
    clock_noise: float = 0.003
    clock_rate_walk: float = 0.02
    gate_late: float = 3.5
    gate_early: float = 6.0
    reset_after: int = 3
    reacquire_after: float = 1.0
    attitude_sigma_deg: float | None = 0.7
    attitude_heading_sigma_deg: float = 5.0
    attitude_rate: float = 10.0
    height_sigma: float = 0.03
    initial_velocity_sigma: float = 0.5
    initial_attitude_sigma_deg: float = 3.0
    initial_acc_bias_sigma: float = 0.1
    initial_gyr_bias_sigma: float = 0.01
    output_time_constant: float = 0.2
    max_output_speed: float = 1.5
    zupt_sigma: float = 0.05
    missing_acc_noise: float = 2.0
    missing_gyr_noise: float = 0.5
    fill_trusted_s: float = 0.05
    smooth: bool = True


@dataclass(frozen=True)
class UnitStart:
    """Where the filter starts (usually from the first good per-transmission fix).

    Attributes:
        time: Start time on the IMU timeline [s].
        p_world_tag: Tag position, shape (3,) [m].
        position_cov: Its covariance, shape (3, 3) [m^2].
        clock: Transmit-time offset from the nominal schedule at ``time`` [m].
        clock_rate: Its rate [m/s].
        clock_sigma: Uncertainty of ``clock`` [m].
        clock_rate_sigma: Uncertainty of ``clock_rate`` [m/s].
    """

    time: float
    p_world_tag: np.ndarray
    position_cov: np.ndarray
    clock: float
    clock_rate: float
    clock_sigma: float
    clock_rate_sigma: float


@dataclass(frozen=True)
class UnitTransmissions:
    """The transmissions of one tag, in time order.

    Attributes:
        time: Transmission time on the IMU timeline, shape (T,) [s].
        seq: Unwrapped transmission numbers, shape (T,) (int64).
        tau_nominal: Nominal transmit time ``c * seq / rate``, shape (T,) [m].
        toa: Times of arrival, shape (T, M) [m], NaN where a reader did not hear.
        fix_p_world_tag: Per-transmission fixes used to reset a diverged filter, shape (T, 3)
            [m], NaN without a fix; or None.
        fix_clock: Their transmit-time offsets from the nominal schedule, shape (T,) [m].
        fix_cov: Their covariances of (x, y, z, transmit time), shape (T, 4, 4) [m^2].
    """

    time: np.ndarray
    seq: np.ndarray
    tau_nominal: np.ndarray
    toa: np.ndarray
    fix_p_world_tag: np.ndarray | None = None
    fix_clock: np.ndarray | None = None
    fix_cov: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass(frozen=True)
class UwbTotals:
    """Totals of a unit's UWB use.

    Attributes:
        transmissions: Transmissions received (by at least one reader).
        transmissions_used: Transmissions with at least one TOA used.
        toas: TOAs received.
        toas_used: TOAs that updated the state.
        toas_rejected: TOAs rejected by the gate.
        resets: Times the gate was re-opened after divergence.
        seconds_without_uwb: Time during which the last used transmission was older than
            0.5 s [s].
    """

    transmissions: int
    transmissions_used: int
    toas: int
    toas_used: int
    toas_rejected: int
    resets: int
    seconds_without_uwb: float


@dataclass(frozen=True)
class UnitTrack:
    """Output of :func:`run_unit_filter`.

    Attributes:
        time: IMU sample times, shape (N,) [s].
        p_world_tag: Tag position, shape (N, 3) [m] (ENU world); NaN before the start.
        cov: Its covariance, shape (N, 3, 3) [m^2]; NaN before the start.
        quat_wxyz_world_sensor: Estimated sensor orientation (w, x, y, z), shape (N, 4).
        tx_time: Transmission times, shape (T,) [s].
        tx_seq: Transmission numbers, shape (T,).
        tx_used: TOAs used per transmission, shape (T, M) (bool).
        tx_rejected: TOAs rejected per transmission, shape (T, M) (bool).
        tx_heard: TOAs received per transmission, shape (T, M) (bool), evaluated or not
            (before the start, none is).
        tx_reset: Transmissions at which the gate re-opened, shape (T,) (bool).
        totals: The :class:`UwbTotals`.
    """

    time: np.ndarray
    p_world_tag: np.ndarray
    cov: np.ndarray
    quat_wxyz_world_sensor: np.ndarray
    tx_time: np.ndarray
    tx_seq: np.ndarray
    tx_used: np.ndarray
    tx_rejected: np.ndarray
    tx_heard: np.ndarray
    tx_reset: np.ndarray
    totals: UwbTotals

    @property
    def used_count(self) -> np.ndarray:
        """TOAs used per transmission, shape (T,)."""
        return self.tx_used.sum(axis=1)

    @property
    def rejected_count(self) -> np.ndarray:
        """TOAs rejected per transmission, shape (T,)."""
        return self.tx_rejected.sum(axis=1)


@dataclass(frozen=True)
class ImuSamples:
    """IMU data of one unit on its own timeline.

    Attributes:
        time: Sample times, shape (N,) [s], increasing.
        acc: Specific force in the sensor frame, shape (N, 3) [m/s^2]; NaN rows are missing.
        gyr: Angular rate in the sensor frame, shape (N, 3) [rad/s]; NaN rows are missing.
        R_world_sensor_aid: Orientation from the IMU's own fusion, shape (N, 3, 3) (NaN where
            unknown), or None.
        height: Tag height aid, shape (N,) [m] (NaN where unknown), or None.
        still: Where the unit stands still (a foot in stance), shape (N,) bool, or None.
    """

    time: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    R_world_sensor_aid: np.ndarray | None = None
    height: np.ndarray | None = None
    still: np.ndarray | None = None


def run_unit_filter(
    imu: ImuSamples,
    transmissions: UnitTransmissions,
    p_world_readers: np.ndarray,
    reader_offsets: np.ndarray,
    start: UnitStart,
    lever_sensor_tag: np.ndarray,
    sigma: float,
    options: EkfOptions | None = None,
) -> UnitTrack:
    """Filter one unit over its whole recording.

    Args:
        imu: The unit's IMU samples.
        transmissions: The tag's transmissions with columns in reader order.
        p_world_readers: Reader positions, shape (M, 3) [m].
        reader_offsets: Reader clock offsets, shape (M,) [m].
        start: Initial tag position and transmit time.
        lever_sensor_tag: Sensor-to-tag lever arm in the sensor frame, shape (3,) [m].
        sigma: TOA noise [m] (``options.sigma`` overrides it).
        options: Tuning.

    Returns:
        The :class:`UnitTrack`.
    """
    opts = options or EkfOptions()
    filt = _UnitFilter(imu, transmissions, p_world_readers, reader_offsets,
                       np.asarray(lever_sensor_tag, dtype=float),
                       opts.sigma if opts.sigma is not None else sigma, opts)
    return filt.run(start)


def _bridge_missing(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows with NaN replaced by linear interpolation between the nearest finite rows.

    Held at the first or last finite row before or after them. A lost packet in the middle of
    a movement is closer to its neighbours' mean than to the last sample (holding it biased the
    smoothed track of a foot by up to 20 cm).

    Returns:
        ``(filled, missing)`` with ``missing`` (N,) True where a row was replaced.
    """
    good = np.isfinite(values).all(axis=1)
    if not good.any():
        return np.zeros_like(values), np.ones(values.shape[0], dtype=bool)
    idx = np.flatnonzero(good)
    k = np.arange(values.shape[0])
    filled = np.stack([np.interp(k, idx, values[idx, i]) for i in range(values.shape[1])],
                      axis=1)
    return filled, ~good


class _UnitFilter:
    """The filter loop; one instance per run, with its preallocated matrices."""

    def __init__(self, imu: ImuSamples, tx: UnitTransmissions, readers: np.ndarray,
                 offsets: np.ndarray, lever: np.ndarray, sigma: float,
                 opts: EkfOptions) -> None:
        self.imu, self.tx, self.readers, self.offsets = imu, tx, readers, offsets
        self.lever, self.sigma, self.opts = lever, float(sigma), opts
        self.acc, missing_acc = _bridge_missing(np.asarray(imu.acc, dtype=float))
        self.gyr, missing_gyr = _bridge_missing(np.asarray(imu.gyr, dtype=float))
        self.missing = missing_acc | missing_gyr
        #: per sample, the time of the last measured sample at or before it [s] (-inf: none)
        self.measured_time = np.maximum.accumulate(
            np.where(self.missing, -np.inf, np.asarray(imu.time, dtype=float)))
        self.q_density = process_noise_diagonal(
            opts.acc_noise, opts.gyr_noise, opts.acc_bias_walk, opts.gyr_bias_walk,
            opts.clock_noise, opts.clock_rate_walk)
        self.q_missing = self.q_density * _MISSING_SAMPLE_INFLATION  # a filled IMU sample
        self.q_missing[VEL] = np.maximum(self.q_missing[VEL], opts.missing_acc_noise**2)
        self.q_missing[ATT] = np.maximum(self.q_missing[ATT], opts.missing_gyr_noise**2)
        self.F = new_transition()
        self.P = np.zeros((N_ERROR, N_ERROR))
        self.x: NominalState | None = None
        self.offset_out = np.zeros(3)
        t_count, m = tx.toa.shape
        self.used = np.zeros((t_count, m), dtype=bool)
        self.rejected = np.zeros((t_count, m), dtype=bool)
        self.reset = np.zeros(t_count, dtype=bool)
        self.bad_in_row = 0
        self.last_used = -math.inf
        self.log = SmootherLog() if opts.smooth else None
        self.marks: dict[int, int] = {}  # recorded sample -> the log step it starts

    # ------------------------------------------------------------------ set-up
    def _initialise(self, start: UnitStart, k: int) -> None:
        opts = self.opts
        self.last_used = float(start.time)
        R0 = self._nearest_aid(k)
        if R0 is None:
            R0 = np.eye(3)
        p_sensor = np.asarray(start.p_world_tag, dtype=float) - R0 @ self.lever
        # The state starts at sample k, up to one interval before the start's own time.
        clock = float(start.clock) - float(start.clock_rate) * (start.time - self.imu.time[k])
        self.x = NominalState(p_sensor, np.zeros(3), matrix_to_quat(R0), np.zeros(3),
                              np.zeros(3), clock, float(start.clock_rate))
        P = self.P
        P[:] = 0.0
        P[POS, POS] = np.asarray(start.position_cov, dtype=float) + 1e-4 * np.eye(3)
        P[VEL, VEL] = opts.initial_velocity_sigma**2 * np.eye(3)
        P[ATT, ATT] = math.radians(opts.initial_attitude_sigma_deg) ** 2 * np.eye(3)
        P[BACC, BACC] = opts.initial_acc_bias_sigma**2 * np.eye(3)
        P[BGYR, BGYR] = opts.initial_gyr_bias_sigma**2 * np.eye(3)
        P[CLOCK, CLOCK] = start.clock_sigma**2
        P[CLOCK_RATE, CLOCK_RATE] = start.clock_rate_sigma**2

    def _nearest_aid(self, k: int) -> np.ndarray | None:
        """The IMU's orientation at sample ``k``, else at the nearest sample that has one.

        A start on a lost packet (the first rows of a sensor lost) must not start the
        attitude at the identity with a small uncertainty.
        """
        aid = self.imu.R_world_sensor_aid
        if aid is None:
            return None
        good = np.flatnonzero(np.isfinite(aid).all(axis=(1, 2)))
        if not len(good):
            return None
        return np.asarray(aid[good[np.argmin(np.abs(good - k))]], dtype=float)

    def _aid(self, k: int) -> np.ndarray | None:
        aid = self.imu.R_world_sensor_aid
        if aid is None or not np.isfinite(aid[k]).all():
            return None
        return np.asarray(aid[k], dtype=float)

    # ------------------------------------------------------------------ main loop
    def run(self, start: UnitStart) -> UnitTrack:
        time = np.asarray(self.imu.time, dtype=float)
        n = time.shape[0]
        p_out = np.full((n, 3), np.nan)
        cov_out = np.full((n, 3, 3), np.nan)
        quat_out = np.full((n, 4), np.nan)
        k0 = int(np.searchsorted(time, start.time, side="right")) - 1
        k0 = min(max(k0, 0), max(n - 1, 0))
        next_tx = int(np.searchsorted(self.tx.time, time[k0], side="left")) if n else 0
        if n:
            self._initialise(start, k0)
            self._record(k0, p_out, cov_out, quat_out, 0.0)
        attitude_every = max(1, round(1.0 / (self.opts.attitude_rate * self._sample_dt(time))))
        for k in range(k0, n - 1):
            next_tx = self._interval(k, time[k], time[k + 1], next_tx)
            if (k + 1 - k0) % attitude_every == 0:
                self._attitude_update(k + 1)
            if self.imu.still is not None and self.imu.still[k + 1]:
                self._zero_velocity_update()
            self._record(k + 1, p_out, cov_out, quat_out, time[k + 1] - time[k])
        if self.log is not None and self.x is not None:
            self._smooth(p_out, cov_out, quat_out)
        return self._result(time, p_out, cov_out, quat_out)

    def _smooth(self, p_out: np.ndarray, cov_out: np.ndarray, quat_out: np.ndarray) -> None:
        """Replace the recorded outputs by the smoothed states at the same samples."""
        assert self.log is not None and self.x is not None
        smoothed = self.log.smooth(self.x, self.P)
        for k, step in self.marks.items():
            x, P = smoothed[step]
            J = tag_position_jacobian(x, self.lever)
            p_out[k] = tag_position(x, self.lever)
            cov_out[k] = J @ P @ J.T
            quat_out[k] = x.quat_wxyz_world_sensor

    @staticmethod
    def _sample_dt(time: np.ndarray) -> float:
        return float(np.median(np.diff(time))) if time.shape[0] > 1 else 0.01

    def _interval(self, k: int, t_a: float, t_b: float, next_tx: int) -> int:
        """Propagate over one IMU interval, processing the transmissions inside it."""
        f = 0.5 * (self.acc[k] + self.acc[k + 1])
        w = 0.5 * (self.gyr[k] + self.gyr[k + 1])
        q_density = self.q_density
        if self.missing[k] or self.missing[k + 1]:
            silent = t_b - float(self.measured_time[k]) > self.opts.fill_trusted_s
            q_density = self.q_missing if silent else self.q_density * _MISSING_SAMPLE_INFLATION
        t = t_a
        tx_time = self.tx.time
        while next_tx < tx_time.shape[0] and tx_time[next_tx] < t_b:
            t_tx = float(tx_time[next_tx])
            if t_tx > t:
                self._propagate(f, w, t_tx - t, q_density)
                t = t_tx
            self._transmission_update(next_tx)
            next_tx += 1
        if t_b > t:
            self._propagate(f, w, t_b - t, q_density)
        return next_tx

    def _propagate(self, f: np.ndarray, w: np.ndarray, dt: float, q_density: np.ndarray
                   ) -> None:
        x = self.x
        assert x is not None
        before = x.copy() if self.log is not None else None
        R_mid = propagate_nominal(x, f, w, dt)  # (the biases stay: the transition uses them)
        f_free, w_free = f - x.b_acc, w - x.b_gyr
        fill_transition(self.F, R_mid, f_free, w_free, dt)
        q = q_density * dt
        if self.log is not None and before is not None:
            self.log.propagated(before, self.P.copy(), (R_mid, f_free, w_free, dt), q, x.copy())
        P = self.F @ self.P @ self.F.T
        P[np.diag_indices(N_ERROR)] += q
        self.P = P

    # ------------------------------------------------------------------ updates
    def _update(self, H: np.ndarray, nu: np.ndarray, noise_var: np.ndarray) -> np.ndarray:
        """Joseph-form EKF update; returns the error-state correction (already injected)."""
        x = self.x
        assert x is not None
        PHt = self.P @ H.T
        S = H @ PHt
        S[np.diag_indices(S.shape[0])] += noise_var
        K = np.linalg.solve(S, PHt.T).T
        dx = K @ nu
        IKH = np.eye(N_ERROR) - K @ H
        P = IKH @ self.P @ IKH.T + (K * noise_var) @ K.T
        self.P = 0.5 * (P + P.T)
        before = tag_position(x, self.lever)
        inject_error(x, dx)
        self.offset_out -= tag_position(x, self.lever) - before
        return dx

    def _gate(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Innovations of transmission ``i``: heard columns, H, nu and the accept mask."""
        x = self.x
        assert x is not None
        z = self.tx.toa[i]
        heard = np.flatnonzero(np.isfinite(z))
        h, H = predict_toa_unit(x, self.lever, self.readers[heard], self.offsets[heard],
                                float(self.tx.tau_nominal[i]))
        nu = z[heard] - h
        s = np.einsum("ij,jk,ik->i", H, self.P, H) + self.sigma**2
        normalised = nu / np.sqrt(s)
        accept = (normalised <= self.opts.gate_late) & (normalised >= -self.opts.gate_early)
        return heard, H, nu, accept

    def _transmission_update(self, i: int) -> None:
        heard, H, nu, accept = self._gate(i)
        if heard.size == 0:
            return
        diverged = heard.size >= 3 and 2 * int(accept.sum()) < heard.size
        self.bad_in_row = self.bad_in_row + 1 if diverged else 0
        t_i = float(self.tx.time[i])
        returning = heard.size >= 4 and t_i - self.last_used > self.opts.reacquire_after
        if self.bad_in_row >= self.opts.reset_after or returning:
            self._reopen(i)
            self.reset[i] = True
            self.bad_in_row = 0
            heard, H, nu, accept = self._gate(i)
        if accept.any():
            self._update(H[accept], nu[accept], np.full(int(accept.sum()), self.sigma**2))
            self.last_used = t_i
        self.used[i, heard[accept]] = True
        self.rejected[i, heard[~accept]] = True
        self._height_update(float(self.tx.time[i]))

    def _reopen(self, i: int) -> None:
        """Re-open the gate: reset to this transmission's fix, or inflate the covariance."""
        x = self.x
        assert x is not None
        tx = self.tx
        has_fix = (tx.fix_p_world_tag is not None and tx.fix_clock is not None
                   and tx.fix_cov is not None and np.isfinite(tx.fix_p_world_tag[i]).all()
                   and np.isfinite(tx.fix_clock[i]))
        P = self.P
        if not has_fix:
            P[POS, POS] += np.eye(3)
            P[VEL, VEL] += np.eye(3)
            P[CLOCK, CLOCK] += 1.0
            return
        assert tx.fix_p_world_tag is not None and tx.fix_clock is not None
        assert tx.fix_cov is not None
        before = tag_position(x, self.lever)
        x.p_world_sensor = tx.fix_p_world_tag[i] - x.R_world_sensor @ self.lever
        x.clock = float(tx.fix_clock[i])
        self.offset_out -= tag_position(x, self.lever) - before
        opts = self.opts
        for block in (POS, VEL, ATT, BACC, slice(CLOCK, CLOCK + 1)):
            P[block, :] = 0.0
            P[:, block] = 0.0
        # Velocity, tilt and accelerometer bias drift together while the filter is lost:
        # give them their initial uncertainty so the next transmissions re-estimate them.
        # The fix's joint covariance of (position, transmit time), so that this
        # transmission's NLOS receptions still stand out against the reset state.
        cov = np.nan_to_num(tx.fix_cov[i])
        pos_clock = [0, 1, 2, CLOCK]
        P[np.ix_(pos_clock, pos_clock)] = cov + 1e-4 * np.eye(4)
        P[VEL, VEL] = (2.0 * opts.initial_velocity_sigma) ** 2 * np.eye(3)
        P[ATT, ATT] = math.radians(opts.initial_attitude_sigma_deg) ** 2 * np.eye(3)
        P[BACC, BACC] = opts.initial_acc_bias_sigma**2 * np.eye(3)

    def _height_update(self, t: float) -> None:
        height = self.imu.height
        if height is None:
            return
        z = float(np.interp(t, self.imu.time, height))
        if not math.isfinite(z):
            return
        x = self.x
        assert x is not None
        H = tag_position_jacobian(x, self.lever)[2:3]
        nu = np.array([z - tag_position(x, self.lever)[2]])
        var = self.opts.height_sigma**2
        if nu[0] ** 2 <= 25.0 * (float((H @ self.P @ H.T)[0, 0]) + var):
            self._update(H, nu, np.array([var]))

    def _zero_velocity_update(self) -> None:
        """The unit stands still: its velocity is zero (within ``zupt_sigma``)."""
        x = self.x
        assert x is not None
        H = np.zeros((3, N_ERROR))
        H[:, VEL] = np.eye(3)
        self._update(H, -np.asarray(x.v_world_sensor, dtype=float),
                     np.full(3, self.opts.zupt_sigma**2))

    def _attitude_update(self, k: int) -> None:
        sigma_deg = self.opts.attitude_sigma_deg
        R_meas = self._aid(k)
        x = self.x
        if sigma_deg is None or R_meas is None or x is None:
            return
        # World-frame residual: R_meas R^T = Exp(R dtheta), so tilt and heading separate.
        R = x.R_world_sensor
        residual = log_so3(R_meas @ R.T)
        if float(residual @ residual) > math.radians(30.0) ** 2:
            # a disturbed aid, unless the filter knows its attitude even less (its IMU was
            # silent): then the attitude restarts from the aid, or it never came back
            if float(np.trace(self.P[ATT, ATT])) > math.radians(30.0) ** 2:
                self._restart_attitude(R_meas)
            return
        H = np.zeros((3, N_ERROR))
        H[:, ATT] = R
        heading_deg = self.opts.attitude_heading_sigma_deg
        var = np.radians([sigma_deg, sigma_deg, heading_deg]) ** 2
        self._update(H, residual, var)

    def _restart_attitude(self, R_world_sensor: np.ndarray) -> None:
        """Take the IMU's own orientation as the attitude, with its initial uncertainty."""
        x = self.x
        assert x is not None
        before = tag_position(x, self.lever)
        x.quat_wxyz_world_sensor = matrix_to_quat(R_world_sensor)
        self.P[ATT, :] = 0.0
        self.P[:, ATT] = 0.0
        self.P[ATT, ATT] = math.radians(self.opts.initial_attitude_sigma_deg) ** 2 * np.eye(3)
        self.offset_out -= tag_position(x, self.lever) - before

    # ------------------------------------------------------------------ output
    def _record(self, k: int, p_out: np.ndarray, cov_out: np.ndarray, quat_out: np.ndarray,
                dt: float) -> None:
        x = self.x
        assert x is not None
        o = self.offset_out
        norm = math.sqrt(float(o @ o))
        if norm > 0.0 and dt > 0.0:
            decay = min(norm * dt / self.opts.output_time_constant,
                        self.opts.max_output_speed * dt, norm)
            o *= 1.0 - decay / norm
        if self.log is not None:
            self.marks[k] = len(self.log)
        J = tag_position_jacobian(x, self.lever)
        p_out[k] = tag_position(x, self.lever) + o
        cov_out[k] = J @ self.P @ J.T + np.outer(o, o)
        quat_out[k] = x.quat_wxyz_world_sensor

    def _result(self, time: np.ndarray, p_out: np.ndarray, cov_out: np.ndarray,
                quat_out: np.ndarray) -> UnitTrack:
        heard = np.isfinite(self.tx.toa)
        used_tx = self.used.any(axis=1)
        totals = UwbTotals(
            transmissions=int(heard.any(axis=1).sum()),
            transmissions_used=int(used_tx.sum()),
            toas=int(heard.sum()),
            toas_used=int(self.used.sum()),
            toas_rejected=int(self.rejected.sum()),
            resets=int(self.reset.sum()),
            seconds_without_uwb=_seconds_without(time, self.tx.time[used_tx], 0.5),
        )
        return UnitTrack(time, p_out, cov_out, quat_out, self.tx.time, self.tx.seq,
                         self.used, self.rejected, heard, self.reset, totals)


def _seconds_without(time: np.ndarray, update_times: np.ndarray, max_age: float) -> float:
    """Total time [s] of IMU intervals whose last update is older than ``max_age`` [s]."""
    if time.shape[0] < 2:
        return 0.0
    last = np.searchsorted(update_times, time[1:], side="right") - 1
    age = np.where(last >= 0, time[1:] - update_times[np.maximum(last, 0)], np.inf)
    return float(np.sum(np.diff(time)[age > max_age]))
