"""Solver settings: weights, limits and thresholds, all from ``configs/solver.yaml``.

The dataclass has no defaults: every value is in the shipped file (its comments give the
units), so the file and the code cannot disagree. A user file with some of the same sections
and keys overrides them (:meth:`SolverSettings.load`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from ..settings_files import ShippedSettings
from .qp import QpSettings

__all__ = ["SolverSettings"]


@dataclass(frozen=True)
class SolverSettings(ShippedSettings):
    """Every tunable of :class:`ikfusion.ik.Solver` (see ``configs/solver.yaml`` for units)."""

    backend: str
    compiled: bool
    max_iterations: int
    first_frame_iterations: int
    step_tolerance: float
    constraint_tolerance: float
    levenberg_marquardt: float
    limit_resolves: int
    limit_crossing_tolerance: float
    projection_steps: int
    qp_max_iterations: int
    qp_slack_weight: float
    qp_relaxed_slack_scale: float
    osqp_tolerance: float
    osqp_max_iterations: int
    orientation: float
    position: float
    posture: float
    posture_joints: dict[str, float]
    posture_axes: dict[str, list[float]]
    assumed: float
    hinge_joints: list[str]
    even_chain: float
    even_chains: list[list[str]]
    chain_share: float
    smoothness_root_translation: float
    smoothness_root_rotation: float
    smoothness_joints: float
    ballistic: float
    takeoff_velocity_tau: float
    continuity: float
    continuity_placed: float
    swing: float
    lag_speed: float
    lag_max: float
    swing_speed: float
    lean_max: float
    lean_speed: float
    touchdown_confirm: float
    ease_speed_deg: float
    persistence: float
    joint_range_margin_deg: float
    joint_range_overshoot_deg: float
    joint_range_settle_s: float
    max_joint_velocity: float
    max_root_velocity: float
    max_root_angular_velocity: float
    contacts: bool
    floor_z: float
    enter_height: float
    enter_speed: float
    enter_relative: float
    leave_relative: float
    leave_distance: float
    settle_speed: float
    tilt_deg: float
    heel_rise_deg: float
    still_relative: float
    reenter_delay: float
    still_rate: float
    still_duration: float
    still_acceleration: float
    rolling_rate: float
    release_speed: float
    speed_window: int
    detection_smoothing: float

    shipped_file = "solver.yaml"
    what = "solver settings"

    @cached_property
    def qp(self) -> QpSettings:
        """The QP backends' iteration limits, tolerances and slack weights (made once)."""
        return QpSettings(self.qp_max_iterations, self.qp_slack_weight,
                          self.qp_relaxed_slack_scale, self.osqp_tolerance,
                          self.osqp_max_iterations)
