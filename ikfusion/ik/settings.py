"""Solver settings: weights, limits and thresholds from ``configs/solver.yaml``."""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..paths import shipped_config
from ..yaml_files import read_yaml


@dataclass(frozen=True)
class SolverSettings:
    """Every tunable of :class:`ikfusion.ik.Solver` (see ``configs/solver.yaml`` for units)."""

    backend: str = "daqp"
    compiled: bool = True
    max_iterations: int = 3
    first_frame_iterations: int = 40
    step_tolerance: float = 0.1
    constraint_tolerance: float = 2e-5
    levenberg_marquardt: float = 1e-9
    orientation: float = 1.0
    position: float = 1.0
    posture: float = 1e-3
    posture_joints: dict[str, float] = field(default_factory=dict)
    posture_axes: dict[str, list[float]] = field(default_factory=dict)
    assumed: float = 0.1
    hinge_joints: list[str] = field(default_factory=lambda: [
        "jRightKnee", "jLeftKnee", "jRightElbow", "jLeftElbow"])
    smoothness_root_translation: float = 1e-6
    smoothness_root_rotation: float = 1e-6
    smoothness_joints: float = 1e-6
    ballistic: float = 1e3
    continuity: float = 3.0
    continuity_placed: float = 1e2
    swing: float = 1e2
    lag_speed: float = 0.2
    lag_max: float = 0.05
    swing_speed: float = 0.4
    lean_max: float = 0.04
    lean_speed: float = 0.1
    ease_speed_deg: float = 20.0
    persistence: float = 1.0
    joint_range_margin_deg: float = 5.0
    max_joint_velocity: float = 30.0
    max_root_velocity: float = 15.0
    max_root_angular_velocity: float = 30.0
    contacts: bool = True
    floor_z: float = 0.0
    enter_height: float = 0.03
    enter_speed: float = 0.5
    enter_relative: float = 0.03
    leave_relative: float = 0.025
    leave_distance: float = 0.02
    settle_speed: float = 0.2
    tilt_deg: float = 5.0
    heel_rise_deg: float = 0.5
    still_relative: float = 0.06
    reenter_delay: float = 0.1
    still_rate: float = 0.6
    still_duration: float = 0.1
    speed_window: int = 1
    detection_smoothing: float = 0.5

    @classmethod
    def load(cls, path: str | Path | None = None, **overrides: Any) -> SolverSettings:
        """Read a solver YAML (sections are flattened); keyword overrides win.

        Raises:
            ConfigError: Unknown keys or values of the wrong type, naming the key.
        """
        file = Path(path) if path is not None else shipped_config("solver.yaml")
        doc = read_yaml(file, "solver settings") or {}
        if not isinstance(doc, dict):
            raise ConfigError("expected a mapping of sections", path=file)
        flat: dict[str, Any] = {}
        for section, values in doc.items():
            if not isinstance(values, dict):
                raise ConfigError("expected a mapping", path=file, field=str(section))
            flat.update(values)
        flat.update(overrides)
        known = {f.name: f for f in fields(cls)}
        for key, value in flat.items():
            if key not in known:
                raise ConfigError(f"unknown setting; known: {', '.join(known)}", path=file,
                                  field=key)
            default = getattr(cls(), key)
            if isinstance(default, int | float) and not isinstance(default, bool):
                if isinstance(value, bool) or not isinstance(value, int | float):
                    raise ConfigError(f"expected a number, found {value!r}", path=file, field=key)
                flat[key] = type(default)(value)
        return replace(cls(), **flat)
