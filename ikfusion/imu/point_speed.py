"""How fast the heel and the ball of a foot move, from the foot's IMU (offline).

A foot rolls over its ball before toe-off: the sensor turns fast while the ball stays put, so
the foot's angular speed cannot say when the ball leaves the floor, and a contact point held
until the sensed pose lifts it is held some 50 ms after it started to slide. The IMU knows more:
integrating the sensor's acceleration without gravity from the last sample where the foot stood
still (its velocity is zero there: pedestrian dead reckoning's zero-velocity update) gives the
sensor's velocity ``v_world_sensor``, and a point rigidly on the foot at ``r`` from the sensor
moves at ``v_world_sensor + omega_world x r``. Offline, the velocity integrated over a stretch
between two still stances is corrected linearly so it ends at zero too (this removes a constant
accelerometer or tilt error). A foot that rolls from heel to ball all through its stance (a brisk
walk) never stands still; its velocity is taken as zero where it turns slowest instead
(:func:`ikfusion.imu.stance.velocity_anchors`). An error that is not constant still grows with
the time integrated, so a sample farther than ``horizon`` from both stances around it (a long
stretch without stance, the end of a recording) has no velocity: the contact detection then
decides without it.

Points below the foot (the toes) are taken at the ball of the foot, where the toes hinge: the
foot pivots about it at push-off.
"""

from __future__ import annotations

import numpy as np

from ..model.human_model import HumanModel
from ..model.topology import BodyTopology
from .flight import world_acceleration


def sensor_velocity(a_world: np.ndarray, still: np.ndarray, rate: float,
                    horizon: float = 0.5) -> np.ndarray:
    """``v_world_sensor`` (N, 3) [m/s] by zero-velocity updates at the still samples.

    Args:
        a_world: (N, 3) the sensor's acceleration without gravity, world frame [m/s^2] (NaN
            where unknown).
        still: (N,) True where the foot stands still (velocity zero).
        rate: Sample rate [Hz].
        horizon: Longest time from a stance over which the integral is trusted [s].

    Returns:
        Zero at still samples; between them the integral of ``a_world`` from the last still
        sample, less a linear ramp that brings it to zero at the next still sample. NaN over a
        moving stretch with an unknown acceleration, and at samples farther than ``horizon``
        from the stances on both sides (a side without a stance counts as infinitely far; on a
        stretch with a stance on one side only, the plain integral from that side).
    """
    n = len(a_world)
    v = np.full((n, 3), np.nan)
    v[still] = 0.0
    edges = np.diff(np.r_[1, still.astype(np.int8), 1])
    dt = 1.0 / rate
    reach = int(np.floor(horizon * rate))
    for start, end in zip(np.flatnonzero(edges == -1), np.flatnonzero(edges == 1)):
        before, after = start > 0, end < n  # a still sample on that side
        a = a_world[max(start - 1, 0):min(end + 1, n)]
        if not (before or after) or not np.isfinite(a).all():
            continue
        steps = np.cumsum(0.5 * (a[1:] + a[:-1]) * dt, axis=0)
        if before and after:  # from zero at the still sample before to zero at the one after
            ramp = np.linspace(0.0, 1.0, len(steps) + 1)[1:, None]
            stretch = (steps - ramp * steps[-1])[:-1]
        elif before:  # the plain integral forward from the last stance
            stretch = steps
        else:  # backward from the next stance (the stretch starts the recording)
            stretch = (np.vstack([np.zeros((1, 3)), steps]) - steps[-1])[:-1]
        k = np.arange(start, end)
        known = ((k - start < reach) if before else False) | ((end - 1 - k < reach) if after
                                                              else False)
        stretch[~known] = np.nan
        v[start:end] = stretch
    return v


def point_velocities(v_world_sensor: np.ndarray, omega_world: np.ndarray,
                     r_world: np.ndarray) -> np.ndarray:
    """Velocities ``v_world_point`` (N, k, 3) [m/s] of points rigidly on the foot.

    Args:
        v_world_sensor: (N, 3) the sensor's velocity [m/s].
        omega_world: (N, 3) the foot's angular velocity in the world frame [rad/s].
        r_world: (N, k, 3) each point's offset from the sensor, world frame [m].
    """
    return np.asarray(v_world_sensor[:, None, :] + np.cross(omega_world[:, None, :], r_world))


def floor_tip_slide(v_world_ball: np.ndarray, p_world_ball: np.ndarray,
                    p_world_tip: np.ndarray) -> np.ndarray:
    """The velocity (3,) [m/s] of a toe tip held on the floor whose ball moves at ``v_world_ball``.

    A tip on the floor moves horizontally, and a rigid toe hinged at the ball moves its tip along
    the line ball -> tip exactly as the ball (a turn about the ball moves the tip only across
    that line). With the toe pitched down by ``a``, a
    horizontal velocity ``s`` along the toe's horizontal direction ``h`` has ``s cos(a)`` along
    the toe, so ``s = (v_ball . u) / cos(a)``: at push-off, with the toe pitched 30-45 deg, the
    tip slides 1.3-2 times faster than the horizontal part of the ball's velocity along the
    toe (``(v_ball . u) cos(a)``), and that is the truth's speed. Across ``h`` it gives nothing
    (a turn about the vertical through the tip), and a ball moving
    more across ``h`` than along it gives no slide at all: the foot spins on its forefoot, and
    the tip moves by that unknown turn. ``s`` is bounded by the ball's own horizontal speed
    along ``h``: a toe that turns further down as the heel rises brings its tip closer to the
    ball horizontally, never faster than it; the bound also keeps a toe pitched near the
    vertical, where ``cos(a)`` vanishes (a solved toe that stands on its tip), from sliding
    faster than its ball.

    Args:
        v_world_ball: (3,) the ball's velocity [m/s].
        p_world_ball: (3,) the ball's position [m].
        p_world_tip: (3,) the toe tip's position [m].
    """
    v_ball = np.asarray(v_world_ball, dtype=float)
    u = np.asarray(p_world_tip, dtype=float) - np.asarray(p_world_ball, dtype=float)
    reach = float(np.hypot(u[0], u[1]))
    if reach <= 0.0:  # a toe standing vertically on its tip
        return np.zeros(3)
    h = u[:2] / reach
    bound = abs(float(v_ball[:2] @ h))
    if bound < abs(float(v_ball[0] * h[1] - v_ball[1] * h[0])):  # more across than along
        return np.zeros(3)
    speed = float(v_ball @ u) / reach  # (v . u / |u|) / cos(a), cos(a) = reach / |u|
    speed = min(max(speed, -bound), bound)
    return np.array([speed * h[0], speed * h[1], 0.0])


def point_speeds(v_world_sensor: np.ndarray, omega_world: np.ndarray,
                 r_world: np.ndarray) -> np.ndarray:
    """Horizontal speeds (N, k) [m/s] of points rigidly on the foot (:func:`point_velocities`)."""
    v = point_velocities(v_world_sensor, omega_world, r_world)
    return np.asarray(np.linalg.norm(v[..., :2], axis=-1))


def foot_point_offsets(model: HumanModel) -> dict[str, dict[str, np.ndarray]]:
    """Per foot segment carrying a sensor site, its contact points' offsets [m] from that site.

    Offsets are in the foot segment frame at the model's neutral pose; a contact point below
    the foot (on the toes) is taken at the origin of its segment, the ball of the foot.
    """
    topology = BodyTopology.of(model)
    q = model.neutral()
    sites = set(model.site_names)
    out: dict[str, dict[str, np.ndarray]] = {}
    for name in topology.contact_points:
        foot = topology.foot_of(name)
        if foot is None or foot not in sites:
            continue
        segment = topology.site_segment[name]
        p = (model.site_position(q, name) if segment == foot
             else model.segment_position(q, segment))
        R_world_foot = model.segment_rotation(q, foot)
        out.setdefault(foot, {})[name] = R_world_foot.T @ (p - model.site_position(q, foot))
    # feet proper only (a heel and toes), not knees or palms
    return {foot: points for foot, points in out.items()
            if any(topology.site_segment[n] != foot for n in points)
            and any(topology.site_segment[n] == foot for n in points)}


def foot_point_velocities(R_world_sensor: np.ndarray, acc: np.ndarray, gyr: np.ndarray,
                          still: np.ndarray, rate: float, R_sensor_segment: np.ndarray,
                          offsets: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each point's velocity ``v_world_point`` (N, 3) [m/s] by the foot's IMU, NaN unknown.

    Args:
        R_world_sensor: (N, 3, 3) the foot sensor's orientations (NaN where missing).
        acc: (N, 3) its specific force, sensor frame [m/s^2].
        gyr: (N, 3) its angular rate, sensor frame [rad/s].
        still: (N,) where the foot's velocity is zero: where it stands still
            (:func:`ikfusion.imu.stance.foot_still`) and, for a foot that rolls through its
            stances, where it turns slowest (:func:`ikfusion.imu.stance.velocity_anchors`).
        rate: Sample rate [Hz].
        R_sensor_segment: (3, 3) the sensor's mounting on the foot segment.
        offsets: Point name -> offset (3,) from the sensor, foot segment frame [m]
            (:func:`foot_point_offsets`).

    Returns:
        Point name -> (N, 3) world velocity [m/s] (:func:`sensor_velocity` plus the turn of
        the foot about the sensor), NaN where the sensor's velocity is unknown.
    """
    v = sensor_velocity(world_acceleration(R_world_sensor, acc), still, rate)
    omega = np.einsum("nij,nj->ni", R_world_sensor, gyr)
    names = list(offsets)
    r_segment = np.stack([offsets[n] for n in names])  # (k, 3)
    r_world = np.einsum("nij,kj->nki", R_world_sensor @ R_sensor_segment, r_segment)
    velocity = point_velocities(v, omega, r_world)
    return {n: velocity[:, i] for i, n in enumerate(names)}


def faster_than(velocities: dict[str, np.ndarray], max_speed: float) -> dict[str, np.ndarray]:
    """Where each point moves horizontally faster than ``max_speed`` [m/s].

    Args:
        velocities: Point name -> (N, 3) velocity [m/s], NaN unknown
            (:func:`foot_point_velocities`).
        max_speed: Horizontal speed above which a point moves [m/s].

    Returns:
        Point name -> (N,) 1.0 moving, 0.0 not, NaN unknown.
    """
    out = {}
    for name, v in velocities.items():
        speed = np.linalg.norm(v[:, :2], axis=1)
        out[name] = np.where(np.isfinite(speed), (speed > max_speed).astype(float), np.nan)
    return out


def points_moving(R_world_sensor: np.ndarray, acc: np.ndarray, gyr: np.ndarray,
                  still: np.ndarray, rate: float, R_sensor_segment: np.ndarray,
                  offsets: dict[str, np.ndarray], max_speed: float) -> dict[str, np.ndarray]:
    """Where each point of a foot moves faster than ``max_speed`` [m/s] by the foot's IMU.

    :func:`faster_than` of :func:`foot_point_velocities` (arguments as there).

    Returns:
        Point name -> (N,) 1.0 moving, 0.0 not, NaN unknown.
    """
    return faster_than(foot_point_velocities(R_world_sensor, acc, gyr, still, rate,
                                             R_sensor_segment, offsets), max_speed)
