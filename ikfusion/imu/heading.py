"""The body heading at the calibration pose, found from the data (no sensor mounting assumed).

In the N-pose every segment frame is ``Rz(heading)`` (SPEC section 1: X forward, Y left, Z up).
Knees and hips flex about the segment Y axis, i.e. about the body's left direction. For a
parent/child pair (thigh -> shank, pelvis -> thigh) the relative rotation after the still window,
taken relative to the N-pose and expressed in the parent sensor frame, is

    v(t) = log( A(t) A0^T ),   A(t) = R_world_parent(t)^T R_world_child(t),   A0 = A(N-pose)

and its dominant direction (principal axis of the v(t)), carried to the world by the parent
sensor's N-pose orientation, is the flexion axis. The left and right knees are averaged with
equal weights: their principal axes lean mirror-wise (internal rotation and abduction couple
with flexion), and the mean cancels the lean; hips are used the same way when no knee moved
(they are checked against the knees otherwise). The sign is fixed so that knees flex backwards:
the shank swings behind the thigh, a positive rotation about the left axis (hips flex forwards,
a negative rotation about it). The heading is that of ``left x up``. The direction walked (the
mean horizontal velocity integrated from the world acceleration after the window) checks it, or
gives it when no leg moved.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..rotations import log_so3
from .still import mean_rotation

#: (parent, child, +1 when flexion is a positive rotation about the left axis, else -1).
FLEXION_PAIRS: tuple[tuple[str, str, float], ...] = (
    ("RightUpperLeg", "RightLowerLeg", 1.0),
    ("LeftUpperLeg", "LeftLowerLeg", 1.0),
    ("Pelvis", "RightUpperLeg", -1.0),
    ("Pelvis", "LeftUpperLeg", -1.0),
)


@dataclass
class FlexionAxis:
    """The dominant relative-rotation axis of one joint after the calibration window.

    Attributes:
        parent: Parent segment.
        child: Child segment.
        left_world: Unit (3,) world direction of the body's left according to this joint.
        amplitude_deg: RMS rotation about the axis [deg].
        purity: Share of the rotation about the axis (1 = a pure hinge).
        knee: Whether the pair is a knee (whose flexion sign is unambiguous).
    """

    parent: str
    child: str
    left_world: np.ndarray
    amplitude_deg: float
    purity: float
    knee: bool


@dataclass
class HeadingEstimate:
    """A heading found from the data.

    Attributes:
        heading: Body heading [rad] (0 = facing +X, East).
        method: How it was found.
        axes: The joints used.
        tilt_deg: How far the combined flexion axis is from horizontal [deg].
        walk_heading: Heading of the direction walked [rad], when found.
        warnings: Doubts worth telling the user.
    """

    heading: float
    method: str
    axes: list[FlexionAxis] = field(default_factory=list)
    tilt_deg: float = 0.0
    walk_heading: float | None = None
    warnings: list[str] = field(default_factory=list)


def flexion_axis(R_parent: np.ndarray, R_child: np.ndarray, window: tuple[int, int],
                 end: int, flexion_sign: float, min_samples: int = 10
                 ) -> tuple[np.ndarray, float, float] | None:
    """Dominant relative-rotation axis of a child sensor w.r.t. its parent after a window.

    Args:
        R_parent: (N, 3, 3) ``R_world_sensor`` of the parent segment's sensor.
        R_child: (N, 3, 3) of the child's sensor.
        window: (start, end) of the N-pose.
        end: Last sample (exclusive) of the movement used.
        flexion_sign: +1 when flexion is a positive rotation about the body's left axis.
        min_samples: Fewest valid samples to decide.

    Returns:
        (left direction in the world (3,), RMS amplitude [deg], purity), or None.
    """
    P0 = mean_rotation(R_parent[window[0]:window[1]])
    A0 = P0.T @ mean_rotation(R_child[window[0]:window[1]])
    A = np.swapaxes(R_parent[window[1]:end], 1, 2) @ R_child[window[1]:end]
    good = np.isfinite(A).all(axis=(1, 2))
    if good.sum() < min_samples:
        return None
    v = log_so3(A[good] @ A0.T)  # relative rotation vectors in the parent sensor frame [rad]
    eigenvalues, vectors = np.linalg.eigh(v.T @ v / len(v))
    axis = vectors[:, -1]
    if flexion_sign * np.mean(v @ axis) < 0.0:  # flexion dominates: make it positive
        axis = -axis
    total = float(eigenvalues.sum())
    purity = float(eigenvalues[-1] / total) if total > 0 else 0.0
    return P0 @ axis, float(np.degrees(np.sqrt(max(eigenvalues[-1], 0.0)))), purity


def heading_of_left(left: np.ndarray) -> float:
    """Heading [rad] of ``left x up`` (the forward direction of a body whose left is ``left``)."""
    return float(np.arctan2(-left[0], left[1]))


def heading_from_flexion(R_world_sensor: Mapping[str, np.ndarray], window: tuple[int, int],
                         rate: float, horizon: float = 20.0, min_amplitude_deg: float = 10.0
                         ) -> HeadingEstimate | None:
    """Heading from the knee and hip flexion axes after the window, or None if too little moved.

    Args:
        R_world_sensor: Segment -> (N, 3, 3) sensor orientations.
        window: (start, end) of the N-pose.
        rate: [Hz].
        horizon: Seconds after the window to use.
        min_amplitude_deg: A joint counts when it rotates at least this much (RMS) [deg].
    """
    end = min(min(len(R) for R in R_world_sensor.values()), window[1] + int(horizon * rate))
    axes = []
    for parent, child, sign in FLEXION_PAIRS:
        if parent in R_world_sensor and child in R_world_sensor:
            found = flexion_axis(R_world_sensor[parent], R_world_sensor[child], window, end, sign)
            if found is not None and found[1] >= min_amplitude_deg:
                axes.append(FlexionAxis(parent, child, found[0], found[1], found[2],
                                        knee=child.endswith("LowerLeg")))
    if not axes:
        return None
    knees = [a for a in axes if a.knee]
    used = knees or axes  # knees are near-pure hinges; hips (which also abduct) when no knee
    # Equal weights for the two sides: a knee's principal axis leans (rotation and abduction
    # couple with flexion) mirror-wise left and right, and the mean cancels that lean.
    left = np.sum([a.left_world for a in used], axis=0)
    if np.linalg.norm(left) < 1e-6:
        return None
    left = left / np.linalg.norm(left)
    horizontal = np.array([left[0], left[1], 0.0])
    if np.linalg.norm(horizontal) < 1e-6:
        return None
    tilt = float(np.degrees(np.arcsin(np.clip(abs(left[2]), 0.0, 1.0))))
    warnings = []
    if tilt > 25.0:
        warnings.append(f"the knee/hip flexion axis is {tilt:.0f} deg off horizontal: was the "
                        "calibration pose upright?")
    for a in axes:
        off = np.degrees(np.arccos(np.clip(abs(a.left_world @ left), -1.0, 1.0)))
        if off > 30.0:
            warnings.append(f"the {_joint_name(a)} flexion axis ({a.parent}->{a.child}) is "
                            f"{off:.0f} deg off the body's left-right axis found: check those "
                            "sensors' segments in the sensor map")
    joints = ", ".join(f"{_joint_name(a)} {a.amplitude_deg:.0f} deg" for a in used)
    method = f"{'knee' if knees else 'hip'} flexion axis ({joints} RMS)"
    return HeadingEstimate(heading_of_left(horizontal), method, axes, tilt, None, warnings)


def _joint_name(axis: FlexionAxis) -> str:
    side = "right" if axis.child.startswith("Right") else "left"
    return f"{side} {'knee' if axis.knee else 'hip'}"


def world_acceleration(R_world_sensor: np.ndarray, acc: np.ndarray | None = None,
                       free_acc: np.ndarray | None = None,
                       gravity: float = 9.81) -> np.ndarray | None:
    """(N, 3) acceleration without gravity in the world [m/s^2], from free acc or acc.

    ``acc`` is the specific force in the sensor frame, ``f = R^T (a - g)``, so
    ``a = R f + g`` with ``g = (0, 0, -gravity)``.
    """
    if free_acc is not None and np.isfinite(free_acc).any():
        return free_acc
    if acc is None or not np.isfinite(acc).any():
        return None
    return np.einsum("nij,nj->ni", R_world_sensor, acc) + np.array([0.0, 0.0, -gravity])


def walking_heading(acc_world: np.ndarray, window: tuple[int, int], rate: float,
                    seconds: float = 6.0, min_speed: float = 0.3,
                    min_straightness: float = 0.8) -> tuple[float, float] | None:
    """Heading [rad] and mean speed [m/s] of the horizontal walk right after a still window.

    The acceleration is de-biased with its mean in the still window, integrated from rest and
    the horizontal velocity averaged over ``seconds``; None below ``min_speed``, and None when
    the mean velocity is shorter than ``min_straightness`` times the mean speed along the path
    (the walk turns, so it has no single direction).
    """
    start, end = window
    stop = min(len(acc_world), end + int(round(seconds * rate)))
    if stop - end < rate:
        return None
    bias = np.nanmean(acc_world[start:end], axis=0)
    a = np.nan_to_num(acc_world[end:stop] - bias)
    velocity = np.cumsum(a, axis=0) / rate
    mean = velocity[:, :2].mean(axis=0)
    speed = float(np.linalg.norm(mean))
    if not np.isfinite(speed) or speed < min_speed:
        return None
    path_speed = float(np.mean(np.linalg.norm(velocity[:, :2], axis=1)))
    if speed < min_straightness * path_speed:
        return None  # the path turns (a circle, a turn on the spot): no single direction
    return float(np.arctan2(mean[1], mean[0])), speed
