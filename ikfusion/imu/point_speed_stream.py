"""How fast the heel and ball of a foot move, sample by sample from the past (live, ``--causal``).

The rule of :mod:`ikfusion.imu.point_speed` without its look-ahead: the sensor's velocity is
integrated from the last sample where the foot stood still, with no correction toward the next
stance (it is not known yet), so an accelerometer or tilt error grows into the velocity with
time. The speeds are therefore trusted only for ``horizon`` seconds after the foot stood still:
long enough to see the ball of a rolling foot leave the floor (within about 0.3 s of foot-flat
in walking), too short for a 0.2 m/s^2 error to reach 0.1 m/s. Later (a whole swing) they are
unknown and the contact detection decides without them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .flight import world_acceleration


class FootPointsStream:
    """Causal moving/not state of the contact points of one foot.

    Args:
        R_sensor_segment: (3, 3) the sensor's mounting on the foot segment.
        offsets: Point name -> offset (3,) from the sensor, foot segment frame [m]
            (:func:`ikfusion.imu.point_speed.foot_point_offsets`).
        max_speed: Horizontal speed above which a point moves [m/s].
        horizon: How long after the last still sample the integrated velocity is trusted [s].
    """

    def __init__(self, R_sensor_segment: np.ndarray, offsets: Mapping[str, np.ndarray],
                 max_speed: float, horizon: float = 0.5) -> None:
        self.R_sensor_segment = np.asarray(R_sensor_segment, dtype=float)
        self.names = list(offsets)
        self.r_segment = np.stack([np.asarray(offsets[n], dtype=float) for n in self.names])
        self.max_speed = max_speed
        self.horizon = horizon
        self._v = np.zeros(3)
        self._last: tuple[float, np.ndarray] | None = None  # time [s], a_world [m/s^2]
        self._still_time: float | None = None  # [s]

    def update(self, time_s: float, R_world_sensor: np.ndarray | None, acc: np.ndarray | None,
               gyr: np.ndarray | None, still: bool | None) -> dict[str, bool]:
        """Point name -> moves, for the points known at this sample (none when unknown).

        Args:
            time_s: Sample time [s].
            R_world_sensor: (3, 3) the foot sensor's orientation, None when missing.
            acc: (3,) its specific force [m/s^2], sensor frame, None when missing.
            gyr: (3,) its angular rate [rad/s], sensor frame, None when missing.
            still: The foot stands still (:class:`~ikfusion.imu.stance_stream.FootStillStream`),
                None when unknown.
        """
        if (R_world_sensor is None or acc is None or gyr is None
                or not (np.isfinite(acc).all() and np.isfinite(gyr).all())):
            self._last, self._still_time = None, None  # the integral is broken
            return {}
        a = world_acceleration(R_world_sensor[None], np.asarray(acc, dtype=float)[None])[0]
        if still:
            self._v = np.zeros(3)
            self._still_time = time_s
        elif self._last is not None and self._still_time is not None:
            t0, a0 = self._last
            self._v = self._v + 0.5 * (a0 + a) * (time_s - t0)
        self._last = (time_s, a)
        if self._still_time is None or time_s - self._still_time > self.horizon:
            return {}
        omega = R_world_sensor @ np.asarray(gyr, dtype=float)
        r_world = (R_world_sensor @ self.R_sensor_segment @ self.r_segment.T).T  # (k, 3)
        v = self._v[None, :] + _cross(omega, r_world)
        speed = np.linalg.norm(v[:, :2], axis=1)
        return {n: bool(s > self.max_speed) for n, s in zip(self.names, speed)}


def _cross(w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(k, 3) ``w x r`` of a (3,) vector and (k, 3) vectors.

    The products and differences of ``np.cross``, which costs ten times more for these few.
    """
    out = np.empty_like(r)
    out[:, 0] = w[1] * r[:, 2] - w[2] * r[:, 1]
    out[:, 1] = w[2] * r[:, 0] - w[0] * r[:, 2]
    out[:, 2] = w[0] * r[:, 1] - w[1] * r[:, 0]
    return out
