"""Models of the IMU + UWB error-state EKF: nominal state, propagation, TOA prediction.

Frames and units: the world is ENU (Z up) [m]; the sensor frame is the IMU's; quaternions are
(w, x, y, z) with ``R_world_sensor = R(quat_wxyz_world_sensor)``. Times of arrival and the
transmit-time states are metres of light travel.

Nominal state (:class:`NominalState`): sensor position and velocity in the world, orientation,
accelerometer and gyroscope biases (sensor frame), and the tag's transmit-time offset
``clock`` [m] relative to its nominal schedule ``c * seq / rate`` with its rate
``clock_rate`` [m/s]. The 17 error states are, in order (see the slice constants)::

    dp (3, world) | dv (3, world) | dtheta (3, sensor: R = R_nom Exp(dtheta)) | dba (3) |
    dbg (3) | dclock (1) | dclock_rate (1)

Continuous error dynamics, with ``f`` the specific force and ``w`` the rate (bias removed)::

    dp' = dv,  dv' = -R [f]x dtheta - R dba - R n_a,  dtheta' = -[w]x dtheta - dbg - n_g,
    dba' = n_ba,  dbg' = n_bg,  dclock' = dclock_rate + n_c,  dclock_rate' = n_cr.

TOA of reader m (SPEC section 4)::

    toa_m = tau_nominal + clock + ||p_world_reader_m - (p + R l)|| + clock_offset_m

with ``l`` the lever arm from the sensor to the tag in the sensor frame [m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..rotations import log_so3, matrix_to_quat_wxyz, rotvec_to_quat_wxyz, skew

#: Gravity in the ENU world frame [m/s^2].
GRAVITY_WORLD = np.array([0.0, 0.0, -9.81])

#: Number of error states.
N_ERROR = 17
#: Error-state slices: position, velocity, attitude, accelerometer bias, gyroscope bias.
POS = slice(0, 3)
VEL = slice(3, 6)
ATT = slice(6, 9)
BACC = slice(9, 12)
BGYR = slice(12, 15)
#: Indices of the transmit-time offset [m] and its rate [m/s].
CLOCK = 15
CLOCK_RATE = 16


@dataclass
class NominalState:
    """The nominal (full) state of one IMU + tag unit.

    Attributes:
        p_world_sensor: Sensor position, shape (3,) [m].
        v_world_sensor: Sensor velocity, shape (3,) [m/s].
        quat_wxyz_world_sensor: Orientation ``R_world_sensor`` as (w, x, y, z), shape (4,).
        b_acc: Accelerometer bias in the sensor frame, shape (3,) [m/s^2].
        b_gyr: Gyroscope bias in the sensor frame, shape (3,) [rad/s].
        clock: Transmit-time offset from the nominal schedule [m].
        clock_rate: Its rate [m/s].
    """

    p_world_sensor: np.ndarray
    v_world_sensor: np.ndarray
    quat_wxyz_world_sensor: np.ndarray
    b_acc: np.ndarray
    b_gyr: np.ndarray
    clock: float = 0.0
    clock_rate: float = 0.0

    def copy(self) -> NominalState:
        """A deep copy."""
        return NominalState(
            self.p_world_sensor.copy(),
            self.v_world_sensor.copy(),
            self.quat_wxyz_world_sensor.copy(),
            self.b_acc.copy(),
            self.b_gyr.copy(),
            self.clock,
            self.clock_rate,
        )

    @property
    def R_world_sensor(self) -> np.ndarray:
        """Orientation as a rotation matrix, shape (3, 3)."""
        return quat_to_matrix(self.quat_wxyz_world_sensor)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of one unit quaternion (w, x, y, z), shape (3, 3)."""
    w, x, y, z = (float(c) for c in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of two quaternions (w, x, y, z)."""
    aw, ax, ay, az = (float(c) for c in a)
    bw, bx, by, bz = (float(c) for c in b)
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), ``w >= 0``, of one rotation matrix."""
    return np.asarray(matrix_to_quat_wxyz(np.asarray(R, dtype=float)), dtype=float).reshape(4)


def propagate_nominal(
    x: NominalState, f_sensor: np.ndarray, w_sensor: np.ndarray, dt: float
) -> np.ndarray:
    """Advance the nominal state in place over ``dt`` with constant inputs.

    The rate is integrated exactly; the specific force is rotated with the mid-step attitude
    and position/velocity integrated as under constant world acceleration.

    Args:
        x: The state (changed in place).
        f_sensor: Specific force in the sensor frame, shape (3,) [m/s^2] (bias not removed).
        w_sensor: Angular rate in the sensor frame, shape (3,) [rad/s] (bias not removed).
        dt: Time step [s].

    Returns:
        ``R_world_sensor`` at mid-step used for the force, shape (3, 3) (for the Jacobian).
    """
    w = (w_sensor - x.b_gyr) * dt
    q0 = x.quat_wxyz_world_sensor
    R_mid = quat_to_matrix(quat_multiply(q0, rotvec_to_quat_wxyz(0.5 * w)))
    a_world = R_mid @ (f_sensor - x.b_acc) + GRAVITY_WORLD
    x.p_world_sensor += x.v_world_sensor * dt + (0.5 * dt * dt) * a_world
    x.v_world_sensor += a_world * dt
    q1 = quat_multiply(q0, rotvec_to_quat_wxyz(w))
    x.quat_wxyz_world_sensor = q1 / math.sqrt(float(q1 @ q1))
    x.clock += x.clock_rate * dt
    return R_mid


def fill_transition(
    F: np.ndarray,
    R_world_sensor: np.ndarray,
    f_sensor: np.ndarray,
    w_sensor: np.ndarray,
    dt: float,
) -> None:
    """Write the error-state transition matrix of one step into ``F`` (17, 17) in place.

    Only the blocks that change are written; ``F`` must start as the identity with its
    ``POS, VEL`` block and ``CLOCK, CLOCK_RATE`` entry set by :func:`new_transition`.

    Args:
        F: The matrix to fill.
        R_world_sensor: Attitude over the step (mid-step), shape (3, 3).
        f_sensor: Bias-corrected specific force, shape (3,) [m/s^2].
        w_sensor: Bias-corrected angular rate, shape (3,) [rad/s].
        dt: Time step [s].
    """
    F[POS, VEL] = np.eye(3) * dt
    F[VEL, ATT] = -(R_world_sensor @ skew(f_sensor)) * dt
    F[VEL, BACC] = -R_world_sensor * dt
    F[ATT, ATT] = quat_to_matrix(rotvec_to_quat_wxyz(-w_sensor * dt))  # Exp(-w dt)
    F[ATT, BGYR] = -np.eye(3) * dt
    F[CLOCK, CLOCK_RATE] = dt


def new_transition() -> np.ndarray:
    """An identity (17, 17) transition matrix to be filled by :func:`fill_transition`."""
    return np.eye(N_ERROR)


def process_noise_diagonal(
    acc_noise: float,
    gyr_noise: float,
    acc_bias_walk: float,
    gyr_bias_walk: float,
    clock_noise: float,
    clock_rate_walk: float,
) -> np.ndarray:
    """Continuous process noise densities per error state, shape (17,) [unit^2 / s].

    Args:
        acc_noise: Accelerometer white noise [m/s^2/sqrt(Hz)].
        gyr_noise: Gyroscope white noise [rad/s/sqrt(Hz)].
        acc_bias_walk: Accelerometer bias random walk [m/s^2/sqrt(s)].
        gyr_bias_walk: Gyroscope bias random walk [rad/s/sqrt(s)].
        clock_noise: Transmit-time white walk [m/sqrt(s)].
        clock_rate_walk: Transmit-time rate random walk [m/s/sqrt(s)].
    """
    q = np.zeros(N_ERROR)
    q[VEL] = acc_noise**2
    q[ATT] = gyr_noise**2
    q[BACC] = acc_bias_walk**2
    q[BGYR] = gyr_bias_walk**2
    q[CLOCK] = clock_noise**2
    q[CLOCK_RATE] = clock_rate_walk**2
    return q


def predict_toa_unit(
    x: NominalState,
    lever_sensor_tag: np.ndarray,
    p_world_readers: np.ndarray,
    reader_offsets: np.ndarray,
    tau_nominal: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted times of arrival and their Jacobian w.r.t. the error state.

    Args:
        x: Nominal state.
        lever_sensor_tag: Sensor-to-tag lever arm in the sensor frame, shape (3,) [m].
        p_world_readers: Positions of the K readers used, shape (K, 3) [m].
        reader_offsets: Their clock offsets, shape (K,) [m].
        tau_nominal: Nominal transmit time ``c * seq / rate`` of the transmission [m].

    Returns:
        ``(toa, H)``: predictions, shape (K,) [m], and ``d toa / d error``, shape (K, 17).
    """
    R = x.R_world_sensor
    p_tag = x.p_world_sensor + R @ lever_sensor_tag
    diff = p_tag[None, :] - p_world_readers
    dist = np.sqrt(np.einsum("ki,ki->k", diff, diff))
    unit = diff / dist[:, None]
    H = np.zeros((p_world_readers.shape[0], N_ERROR))
    H[:, POS] = unit
    H[:, ATT] = -unit @ (R @ skew(lever_sensor_tag))
    H[:, CLOCK] = 1.0
    toa = (tau_nominal + x.clock) + dist + reader_offsets
    return toa, H


def tag_position(x: NominalState, lever_sensor_tag: np.ndarray) -> np.ndarray:
    """Tag position ``p + R l`` in the world, shape (3,) [m]."""
    return x.p_world_sensor + x.R_world_sensor @ lever_sensor_tag


def tag_position_jacobian(x: NominalState, lever_sensor_tag: np.ndarray) -> np.ndarray:
    """``d p_world_tag / d error``, shape (3, 17)."""
    J = np.zeros((3, N_ERROR))
    J[:, POS] = np.eye(3)
    J[:, ATT] = -(x.R_world_sensor @ skew(lever_sensor_tag))
    return J


def inject_error(x: NominalState, dx: np.ndarray) -> None:
    """Add an error-state correction ``dx`` (17,) to the nominal state in place."""
    x.p_world_sensor += dx[POS]
    x.v_world_sensor += dx[VEL]
    q = quat_multiply(x.quat_wxyz_world_sensor, rotvec_to_quat_wxyz(dx[ATT]))
    x.quat_wxyz_world_sensor = q / math.sqrt(float(q @ q))
    x.b_acc += dx[BACC]
    x.b_gyr += dx[BGYR]
    x.clock += float(dx[CLOCK])
    x.clock_rate += float(dx[CLOCK_RATE])


def state_difference(x_a: NominalState, x_b: NominalState) -> np.ndarray:
    """The error state (17,) that :func:`inject_error` adds to ``x_b`` to give ``x_a``."""
    d = np.empty(N_ERROR)
    d[POS] = x_a.p_world_sensor - x_b.p_world_sensor
    d[VEL] = x_a.v_world_sensor - x_b.v_world_sensor
    d[ATT] = log_so3(x_b.R_world_sensor.T @ x_a.R_world_sensor)
    d[BACC] = x_a.b_acc - x_b.b_acc
    d[BGYR] = x_a.b_gyr - x_b.b_gyr
    d[CLOCK] = x_a.clock - x_b.clock
    d[CLOCK_RATE] = x_a.clock_rate - x_b.clock_rate
    return d
