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
        root_position: Optional target for the pelvis origin ``p_world_pelvis`` [m] (a planner's
            or a ballistic path), with weight ``root_position_weight`` [1/m^2].
        angular_speeds: Segment name -> angular speed [rad/s] from its gyroscope, when the
            recording has one (contact detection uses the feet's).
    """

    time: float
    orientations: Mapping[str, np.ndarray] = field(default_factory=dict)
    positions: Mapping[str, np.ndarray] = field(default_factory=dict)
    contacts: Mapping[str, bool] | None = None
    orientation_weights: Mapping[str, float] = field(default_factory=dict)
    position_weights: Mapping[str, float | np.ndarray] = field(default_factory=dict)
    root_position: np.ndarray | None = None
    root_position_weight: float = 1.0
    angular_speeds: Mapping[str, float] = field(default_factory=dict)
