"""Simulated body-worn IMUs from a ground-truth motion: orientations, specific force, rate.

Per sensor site (SPEC section 2), the sensor is strapped with a mounting rotation
``R_segment_sensor`` (random by default, as real straps are) and reports what an Xsens
MTw-class unit reports:

* ``R_world_sensor``: the true orientation with smooth, slowly varying errors (default 0.5 deg
  RMS tilt over about a second, 1.5 deg heading over about ten), a little white noise and a
  heading random walk (default about 1 deg per minute), the errors of magnetometer-aided
  orientation filters indoors (see :class:`ImuNoise` for what real files show);
* ``acc``: specific force ``R_world_sensor^T (a_world - g)`` [m/s^2] in the sensor frame, with
  white noise and a constant bias;
* ``gyr``: angular rate in the sensor frame [rad/s], with white noise and a constant bias.

Accelerations and rates come from the true kinematics by central differences of the sensor
site position and orientation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import solve_discrete_lyapunov
from scipy.signal import lfilter

from ..model.human_model import HumanModel
from ..rotations import axis_rotation, exp_so3, log_so3, random_rotations

GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class ImuNoise:
    """Sensor error model (standard deviations; angles in degrees where named ``_deg``).

    The orientation a sensor reports comes out of its own fusion filter: its error is of the
    size the datasheets give (Xsens MTw: 0.75 deg roll/pitch, 1.5 deg heading RMS in motion)
    but varies slowly, like the filter's state: the filter turns its orientation as the
    gyroscope says and corrects it a little at every sample (tilt through gravity, within
    about a second; heading through the magnetometer, over ten seconds and more). Measured on
    every real file with orientations in ``../shared/data`` (``benchmarks/bench_sensor_noise.py``;
    26 MTx/MTw/MTw2 sensors of static11, opensense_walk, movingreality_trial007 and formats at
    100 Hz, 11 MVNX sensors at 60 Hz): standing still (turning slower than 2 deg/s over 0.1 s)
    the reported orientation turns 0.003-0.017 deg per 100 Hz sample (median 0.013; MVNX
    0.017-0.031 deg per 60 Hz frame), and in any motion, treadmill gait included, a sample's
    turn departs from the sensor's own gyroscope by 0.0005-0.007 deg (median 0.002, bias
    removed). So the slow errors are smooth: each is white noise through two first-order lags
    of its time constant (a critically damped second-order Gauss-Markov process), which turns
    by ``rms * dt / tau`` per sample (about 0.005 deg per 100 Hz sample with the defaults)
    where one lag turns by ``rms * sqrt(2 dt / tau)`` (0.27 deg with the former single 0.1 s
    tilt lag, 20 times the real files). The white noise is of the size of integrated
    gyroscope noise; the heading random walk passes the heading lag too.

    Attributes:
        tilt_deg: RMS of the slowly varying error about the horizontal axes, both together
            [deg].
        heading_deg: RMS of the slowly varying error about the vertical [deg].
        tilt_correlation_s: Time constant of each of the tilt error's two lags [s] (0: white).
        heading_correlation_s: Time constant of each of the heading error's two lags, and of
            the lag the heading walk passes [s] (0: white).
        white_deg: White orientation noise per sample, each axis [deg].
        heading_walk_deg_per_sqrt_s: Heading random walk [deg/sqrt(s)].
        acc: White accelerometer noise [m/s^2].
        acc_bias: Accelerometer bias, drawn once per sensor [m/s^2].
        gyr: White gyroscope noise [rad/s].
        gyr_bias: Gyroscope bias, drawn once per sensor [rad/s].
    """

    tilt_deg: float = 0.5
    heading_deg: float = 1.5
    tilt_correlation_s: float = 1.0
    heading_correlation_s: float = 10.0
    white_deg: float = 0.0005
    heading_walk_deg_per_sqrt_s: float = 0.13
    acc: float = 0.05
    acc_bias: float = 0.05
    gyr: float = 0.005
    gyr_bias: float = 0.002

    @classmethod
    def none(cls) -> ImuNoise:
        """Perfect sensors."""
        return cls(tilt_deg=0.0, heading_deg=0.0, white_deg=0.0, heading_walk_deg_per_sqrt_s=0.0,
                   acc=0.0, acc_bias=0.0, gyr=0.0, gyr_bias=0.0)


@dataclass
class SimulatedImus:
    """Sensor streams of one capture.

    Attributes:
        time: (N,) [s].
        segments: Segment carrying each sensor, (S,).
        R_segment_sensor: Mounting rotations (S, 3, 3).
        R_world_sensor: Reported orientations (S, N, 3, 3).
        acc: Specific force in the sensor frame (S, N, 3) [m/s^2].
        gyr: Angular rate in the sensor frame (S, N, 3) [rad/s].
    """

    time: np.ndarray
    segments: list[str]
    R_segment_sensor: np.ndarray
    R_world_sensor: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray


def _central_difference(x: np.ndarray, dt: float) -> np.ndarray:
    """Derivative along axis 0 (central inside, one-sided at the ends)."""
    return np.gradient(x, dt, axis=0)


def simulate_imus(model: HumanModel, time: np.ndarray, q: np.ndarray, segments: Sequence[str],
                  rng: np.random.Generator, noise: ImuNoise | None = None,
                  random_mounting: bool = True) -> SimulatedImus:
    """Simulate the IMUs on ``segments`` along the configurations ``q`` (N, nq).

    Args:
        model: The human model (sensor sites are named like their segments).
        time: (N,) sample times [s], uniformly spaced.
        q: (N, nq) true configurations.
        segments: Segments carrying a sensor.
        rng: Random generator (mounting, noise, biases).
        noise: Error model; :class:`ImuNoise` defaults when omitted, ``ImuNoise.none()`` for
            perfect sensors.
        random_mounting: Strap each sensor with a uniformly random rotation (else aligned).

    Returns:
        The :class:`SimulatedImus`.
    """
    noise = noise if noise is not None else ImuNoise()
    n, s = len(time), len(segments)
    dt = float(np.mean(np.diff(time))) if n > 1 else 1.0
    data = model.model.createData()
    frames = [model.site_frame_id(seg) for seg in segments]
    R_site = np.empty((s, n, 3, 3))
    p_site = np.empty((s, n, 3))
    for k in range(n):
        pin.framesForwardKinematics(model.model, data, q[k])
        for i, f in enumerate(frames):
            R_site[i, k] = data.oMf[f].rotation
            p_site[i, k] = data.oMf[f].translation
    mounting = random_rotations(s, rng) if random_mounting else np.tile(np.eye(3), (s, 1, 1))
    R_true = R_site @ mounting[:, None]
    acc_world = np.stack([_central_difference(_central_difference(p_site[i], dt), dt)
                          for i in range(s)])
    f_world = acc_world - GRAVITY
    acc = np.einsum("snji,snj->sni", R_true, f_world)
    rel = log_so3(np.swapaxes(R_true[:, :-1], -1, -2) @ R_true[:, 1:]) / dt  # sensor frame
    gyr = np.empty((s, n, 3))
    gyr[:, 1:-1] = 0.5 * (rel[:, :-1] + rel[:, 1:])
    gyr[:, 0], gyr[:, -1] = rel[:, 0], rel[:, -1]
    acc += noise.acc * rng.normal(size=acc.shape) + noise.acc_bias * rng.normal(size=(s, 1, 3))
    gyr += noise.gyr * rng.normal(size=gyr.shape) + noise.gyr_bias * rng.normal(size=(s, 1, 3))
    R_reported = _orientation_errors(R_true, noise, dt, rng)
    return SimulatedImus(np.asarray(time, dtype=float), list(segments), mounting, R_reported,
                         acc, gyr)


def _orientation_errors(R_true: np.ndarray, noise: ImuNoise, dt: float,
                        rng: np.random.Generator) -> np.ndarray:
    """Left-multiply world-frame errors: slow tilt/heading errors, white noise, heading walk."""
    s, n = R_true.shape[:2]
    sigma = np.radians([noise.tilt_deg / np.sqrt(2), noise.tilt_deg / np.sqrt(2),
                        noise.heading_deg])
    tau = np.array([noise.tilt_correlation_s, noise.tilt_correlation_s,
                    noise.heading_correlation_s])
    slow = sigma * _smooth_gauss_markov(rng.normal(size=(s, n + 2, 3)), dt, tau)
    white = np.radians(noise.white_deg) * rng.normal(size=(s, n, 3))
    walk = np.radians(noise.heading_walk_deg_per_sqrt_s) * np.sqrt(dt) * np.cumsum(
        rng.normal(size=(s, n)), axis=1)
    walk = _lag(walk, _lag_factor(noise.heading_correlation_s, dt), walk[:, 0])
    E = exp_so3(slow + white) @ axis_rotation("z", walk)
    return E @ R_true


def _lag_factor(tau: float, dt: float) -> float:
    """Factor ``exp(-dt / tau)`` of a first-order lag sampled every ``dt`` [s] (0 when tau <= 0)."""
    return float(np.exp(-dt / tau)) if tau > 0 else 0.0


def _lag(x: np.ndarray, a: float, start: np.ndarray) -> np.ndarray:
    """First-order lag along axis 1, ``y_k = a y_(k-1) + (1 - a) x_k`` from ``y_(-1) = start``."""
    return lfilter([1.0 - a], [1.0, -a], x, axis=1, zi=(a * start)[:, None])[0]


def _smooth_gauss_markov(draws: np.ndarray, dt: float, tau: np.ndarray) -> np.ndarray:
    """Unit-variance critically damped second-order Gauss-Markov series along axis 1.

    White noise passes two first-order lags in a row; the two lag states start from their
    stationary joint distribution, so the series is stationary from its first sample.

    Args:
        draws: (s, n + 2, 3) independent standard normal samples: two start each series.
        dt: Sample period [s].
        tau: (3,) time constant of the lags of each axis [s]; 0 gives white noise.

    Returns:
        (s, n, 3) series of unit variance.
    """
    out = np.empty((draws.shape[0], draws.shape[1] - 2, 3))
    for axis in range(3):
        a = _lag_factor(float(tau[axis]), dt)
        if a == 0.0:
            out[:, :, axis] = draws[:, 2:, axis]
            continue
        # state z = (first lag, second lag): z_k = A z_(k-1) + B e_k with e_k of unit variance
        A = np.array([[a, 0.0], [(1.0 - a) * a, a]])
        B = np.array([[1.0], [1.0 - a]])
        P = solve_discrete_lyapunov(A, B @ B.T)
        start = draws[:, :2, axis] @ np.linalg.cholesky(P).T
        first = lfilter([1.0], [1.0, -a], draws[:, 2:, axis], axis=1,
                        zi=a * start[:, :1])[0]
        out[:, :, axis] = _lag(first, a, start[:, 1]) / np.sqrt(P[1, 1])
    return out
