"""Smooth motions with known truth for the solver tests."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ikfusion.ik import Frame
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.sim.truth import orientation_frames, with_feet_still


def angle_limits(model: HumanModel) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = [], []
    for joint in model.ball_joints.values():
        for name in ("flex", "abd", "rot"):
            spec = next(a for a in joint.spec.angles if a.name == name)
            lo.append(spec.lower_deg)
            hi.append(spec.upper_deg)
    return np.array(lo), np.array(hi)


def smooth_motion(model: HumanModel, rng: np.random.Generator, frames: int, keys: int = 5,
                  margin_deg: float = 3.0, fixed: dict[str, float] | None = None) -> np.ndarray:
    """Configurations interpolated smoothly between random keyframes in anatomical-angle space
    (so every frame stays inside the ranges of motion), with a turning pelvis."""
    lo, hi = angle_limits(model)
    columns = model.angle_columns
    inside = np.minimum(margin_deg, 0.25 * (hi - lo))  # narrow ranges (the toes' twist)
    key_angles = rng.uniform(lo + inside, hi - inside, size=(keys, len(columns)))
    key_yaw = rng.uniform(-np.pi, np.pi, size=keys)
    qs = []
    for k in range(frames):
        s = k / (frames - 1) * (keys - 1)
        i = min(int(s), keys - 2)
        a = s - i
        a = a * a * (3 - 2 * a)
        angles = dict(zip(columns, key_angles[i] * (1 - a) + key_angles[i + 1] * a))
        angles.update(fixed or {})
        yaw = key_yaw[i] * (1 - a) + key_yaw[i + 1] * a
        R = pin.utils.rotate("z", yaw)
        qs.append(model.configuration(angles, R_world_pelvis=R))
    return np.array(qs)


def frames_from(model: HumanModel, qs: np.ndarray, rate: float = 60.0,
                segments: tuple[str, ...] = SENSOR_SEGMENTS, stance: bool = False
                ) -> list[Frame]:
    """Exact orientation targets; with ``stance``, also the feet's stance from them."""
    frames = orientation_frames(model, qs, np.arange(len(qs)) / rate, segments)
    return with_feet_still(frames, rate) if stance else frames


def observable_columns(model: HumanModel,
                       segments: tuple[str, ...] = SENSOR_SEGMENTS) -> list[int]:
    """Angle columns of joints whose parent and child segments both carry a sensor."""
    tracked = set(segments)
    joints = [name for name, j in model.ball_joints.items()
              if j.spec.parent in tracked and j.spec.child in tracked]
    return [k for k, c in enumerate(model.angle_columns) if c.rsplit("_", 1)[0] in joints]


def wrap_deg(x: np.ndarray) -> np.ndarray:
    return (x + 180.0) % 360.0 - 180.0
