"""One frame of targets for the solver."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Frame:
    """Targets at one instant.

    Attributes:
        time: [s].
        orientations: Segment name -> ``R_world_segment`` (3, 3). Absent (or NaN) segments are
            not tracked this frame.
        positions: Site name -> ``p_world_site`` (3,) [m].
        contacts: Optional hints, contact point name -> in contact; they override detection.
        orientation_weights: Segment name -> weight (default 1; 0 switches a segment off, e.g.
            a sample flagged invalid by the reader).
        position_weights: Site name -> scalar weight [1/m^2] or (3, 3) information matrix.
        position_reach: Optional bound [m] on how far a site target pulls in one step: a
            farther target acts as if it were this far (a correction at a bounded rate).
        shape_positions: Site name -> ``p_world_site`` (3,) [m] reached only by how the
            unsensed columns (spine, neck) share their bend (:class:`ikfusion.ik.tasks.
            ColumnShapeTask`: a head's tag shaping the trunk), with ...
        shape_weights: ... site name -> (3, 3) information matrix [1/m^2] (or a scalar) ...
        shape_reach: ... and an optional bound [m] on how far such a target pulls in one step
            (as ``position_reach``).
        root_position: Optional target for the pelvis origin ``p_world_pelvis`` [m] (a planner's
            or a ballistic path), with weight ``root_position_weight`` [1/m^2].
        feet_still: Segment carrying contact points -> its IMU says they stand still: a foot
            (``LeftFoot``/``RightFoot``) by its gyroscope
            (:func:`ikfusion.imu.stance.foot_still`), a shin, hand, pelvis or upper trunk (knee,
            palm, sacrum and buttocks, shoulder blades and chest) by its
            accelerometer (:func:`ikfusion.imu.resting.segment_resting`); absent when unknown.
            Contact detection keeps a still foot planted and hands the body over to it.
        points_moving: Contact point name -> its foot's IMU says the point moves (faster than
            ``release_speed``, :func:`ikfusion.imu.point_speed.points_moving`); absent when
            unknown. A planted point that moves lets go.
        points_velocity: Contact point name -> ``v_world_point`` (3,) [m/s], its velocity by
            its foot's IMU (:func:`ikfusion.imu.point_speed.foot_point_velocities`), when known
            and wanted (IMU only: without absolute positions this is the only word on whether
            a held point truly stands). A planted point carries its anchor along horizontally
            at this velocity: a push-off toe that drags, a heel that lands still travelling.
        airborne: The body is in the air (:func:`ikfusion.imu.flight.detect_flight`): no point
            is planted and none touches down; the pelvis flies on the ballistic path from its
            take-off velocity. A contact hint takes precedence for its own point.
        root_acceleration: ``a_world_pelvis`` (3,) [m/s^2], the pelvis IMU's acceleration in
            the world frame (gravity removed), when recorded: it keeps the pelvis velocity
            honest across take-offs (:mod:`ikfusion.ik.ballistic`).
        orientations_stacked: The values of ``orientations`` (k, 3, 3) stacked in its order,
            when whoever makes the frame holds them so (the solver then need not stack them
            every frame); None: the solver stacks them. A frame replaced with other
            orientations must leave it None (``dataclasses.replace(frame, orientations=...,
            orientations_stacked=None)``): the solver reads these values, not the mapping's.
    """

    time: float
    orientations: Mapping[str, np.ndarray] = field(default_factory=dict)
    positions: Mapping[str, np.ndarray] = field(default_factory=dict)
    contacts: Mapping[str, bool] | None = None
    orientation_weights: Mapping[str, float] = field(default_factory=dict)
    position_weights: Mapping[str, float | np.ndarray] = field(default_factory=dict)
    position_reach: float | None = None
    shape_positions: Mapping[str, np.ndarray] = field(default_factory=dict)
    shape_weights: Mapping[str, float | np.ndarray] = field(default_factory=dict)
    shape_reach: float | None = None
    root_position: np.ndarray | None = None
    root_position_weight: float = 1.0
    feet_still: Mapping[str, bool] = field(default_factory=dict)
    points_moving: Mapping[str, bool] = field(default_factory=dict)
    points_velocity: Mapping[str, np.ndarray] = field(default_factory=dict)
    airborne: bool = False
    root_acceleration: np.ndarray | None = None
    orientations_stacked: np.ndarray | None = None
