"""Retargeting solve settings, from ``configs/retarget/defaults.yaml`` and the robot's config.

The dataclass has no defaults: every value is in the shipped defaults file (its comments give
the units), and a robot config may override some under its ``solver`` key.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..paths import shipped_config
from ..settings_files import Overlay, load_settings
from ..yaml_files import YamlDocument

__all__ = ["RetargetSettings"]


@dataclass(frozen=True)
class RetargetSettings:
    """Weights, step counts and tolerances of :class:`ikfusion.retarget.robot.RobotRetargeter`.

    Attributes:
        orientation_weight: Weight of each mapped link's orientation [1/rad^2].
        flat_foot_weight: Weight pulling a foot whose source foot is in contact flat onto the
            floor [1/rad^2, 1/m^2].
        smoothness: Toward the previous frame (root and joints) [1/m^2, 1/rad^2].
        rest_pull: Toward the rest pose, for joints the tasks leave open [1/rad^2].
        levenberg_marquardt: Damping added to the QP's Hessian diagonal.
        backend: QP backend (qpsolvers name).
        max_steps: Gauss-Newton steps per frame at most ...
        first_frame_steps: ... on the first frame.
        first_frame_starts: The first frame is solved from the rest pose and from this many
            minus one random arm poses ...
        first_frame_screen_steps: ... in rounds of this many steps, each keeping the better
            half, until the best is solved on.
        step_tolerance: A frame is done after a step whose largest component is below this
            [rad or m] ...
        hold_tolerance: ... with planted feet held this well [m, rad].
        trust_step: Largest joint step while capsule rows are active [rad] ...
        trusted_steps: ... in a frame's first this many steps.
        capsules_far: Capsule pairs this far apart [m] have no rows after a small step.
        plant_height: A foot plants once its lowest sole corner is this close to the floor [m]
            ...
        plant_wait: ... or this long after its source foot touched down [s].
        max_root_velocity: Root speed bound [m/s].
        max_root_angular_velocity: Root angular speed bound [rad/s].
    """

    orientation_weight: float
    flat_foot_weight: float
    smoothness: float
    rest_pull: float
    levenberg_marquardt: float
    backend: str
    max_steps: int
    first_frame_steps: int
    first_frame_starts: int
    first_frame_screen_steps: int
    step_tolerance: float
    hold_tolerance: float
    trust_step: float
    trusted_steps: int
    capsules_far: float
    plant_height: float
    plant_wait: float
    max_root_velocity: float
    max_root_angular_velocity: float

    @classmethod
    def load(cls, robot_config: YamlDocument | None = None,
             **overrides: Any) -> RetargetSettings:
        """The shipped defaults, overlaid by a robot config's ``solver`` key; keywords win.

        Raises:
            ConfigError: An unknown key, a key in the wrong section or a value of the wrong
                type, naming the file, the line and the key.
        """
        overlays = [] if robot_config is None else [Overlay(robot_config, ("solver",))]
        return load_settings(cls, shipped_config("retarget", "defaults.yaml"),
                             "retarget settings", overlays, overrides)
