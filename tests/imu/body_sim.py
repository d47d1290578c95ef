"""A small body-worn sensor simulator for the calibration tests (no solver, no URDF).

Segment orientations of a simple walk are built joint by joint in the MVN convention (X forward,
Y left, Z up; every segment parallel to ``Rz(heading)`` in the N-pose):

* a still N-pose, then the gait fades in over one second;
* hips flex (thigh forward: a negative rotation about Y) 10 +- 20 deg, with mirrored abduction
  and rotation; knees flex (a positive rotation about Y, the shank swings back) 2-58 deg, with a
  mirrored screw-home rotation; ankles, pelvis and trunk sway a little; arms swing;
* the pelvis walks forward at up to 1.2 m/s, bobbing 2 cm.

Sensors are strapped with random mountings ``R_segment_sensor``; they report
``R_world_sensor = R_world_segment @ R_segment_sensor`` (optionally with white orientation noise
in the sensor frame), the angular rate in the sensor frame and, for the pelvis, the specific
force ``R_world_sensor^T (a - g)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ikfusion.rotations import axis_rotation, exp_so3, log_so3, random_rotations

SEGMENTS17 = ("Pelvis", "T8", "Head", "RightShoulder", "RightUpperArm", "RightForeArm",
              "RightHand", "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
              "RightUpperLeg", "RightLowerLeg", "RightFoot", "LeftUpperLeg", "LeftLowerLeg",
              "LeftFoot")


@dataclass
class SimulatedBody:
    """Truth and sensor streams (dicts keyed by segment)."""

    rate: float
    time: np.ndarray
    heading: float
    R_world_segment: dict[str, np.ndarray]
    R_segment_sensor: dict[str, np.ndarray]
    R_world_sensor: dict[str, np.ndarray]
    gyr: dict[str, np.ndarray]
    acc: dict[str, np.ndarray]
    p_world_pelvis: np.ndarray


def _rx(deg: np.ndarray) -> np.ndarray:
    return axis_rotation("x", np.radians(deg))


def _ry(deg: np.ndarray) -> np.ndarray:
    return axis_rotation("y", np.radians(deg))


def _rz(deg: np.ndarray) -> np.ndarray:
    return axis_rotation("z", np.radians(deg))


def body_motion(time: np.ndarray, stand: float, heading_deg: float,
                walk: bool = True) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """``R_world_segment`` (N, 3, 3) of the 17 sensor segments and the pelvis position [m]."""
    t = np.maximum(time - stand, 0.0)
    e = np.clip(t, 0.0, 1.0) ** 2 * (3 - 2 * np.clip(t, 0.0, 1.0)) if walk else 0.0 * t
    phase = 2 * np.pi * 0.9 * t
    out: dict[str, np.ndarray] = {}
    pelvis = _rz(heading_deg + e * 4 * np.sin(phase)) @ _rx(e * 3 * np.sin(phase))
    out["Pelvis"] = pelvis
    out["T8"] = pelvis @ _ry(e * 3 * np.sin(2 * phase)) @ _rz(-e * 5 * np.sin(phase))
    out["Head"] = out["T8"] @ _rz(e * 3 * np.sin(phase))
    for side, shift, mirror in (("Right", 0.0, 1.0), ("Left", np.pi, -1.0)):
        p = phase + shift
        hip = (_ry(-e * (10 + 20 * np.sin(p))) @ _rx(mirror * e * 4 * np.sin(p + 0.4))
               @ _rz(mirror * e * 3 * np.sin(p)))
        knee_deg = e * (30 - 28 * np.cos(p - 1.2))
        knee = _ry(knee_deg) @ _rz(-mirror * 0.08 * knee_deg)
        thigh = pelvis @ hip
        shank = thigh @ knee
        out[f"{side}UpperLeg"] = thigh
        out[f"{side}LowerLeg"] = shank
        out[f"{side}Foot"] = shank @ _ry(e * 10 * np.sin(p + 2.0))
        shoulder = out["T8"]
        out[f"{side}Shoulder"] = shoulder
        upper = shoulder @ _ry(e * 15 * np.sin(p + np.pi))
        out[f"{side}UpperArm"] = upper
        out[f"{side}ForeArm"] = upper @ _ry(-e * (20 + 10 * np.sin(p)))
        out[f"{side}Hand"] = out[f"{side}ForeArm"]
    forward = np.array([np.cos(np.radians(heading_deg)), np.sin(np.radians(heading_deg)), 0.0])
    speed = 1.2 * e
    distance = np.cumsum(speed) * (time[1] - time[0])
    p_world = distance[:, None] * forward + np.array([0.0, 0.0, 0.95])
    p_world[:, 2] += e * 0.02 * np.sin(2 * phase)
    return out, p_world


def angular_rate(R: np.ndarray, rate: float) -> np.ndarray:
    """(N, 3) body-frame angular rate [rad/s] by central differences of orientations."""
    forward = log_so3(np.swapaxes(R[:-1], 1, 2) @ R[1:]) * rate
    w = np.empty((len(R), 3))
    w[0], w[-1] = forward[0], forward[-1]
    w[1:-1] = 0.5 * (forward[:-1] + forward[1:])
    return w


def simulate(rng: np.random.Generator, seconds: float = 9.0, stand: float = 2.5,
             rate: float = 60.0, heading_deg: float = 70.0, noise_deg: float = 0.0,
             walk: bool = True, segments: tuple[str, ...] = SEGMENTS17,
             mounting: dict[str, np.ndarray] | None = None) -> SimulatedBody:
    """Simulate the sensors of ``segments`` on the walk."""
    time = np.arange(int(seconds * rate)) / rate
    R_seg, p = body_motion(time, stand, heading_deg, walk)
    mounts = dict(zip(segments, random_rotations(len(segments), rng)))
    mounts.update(mounting or {})
    velocity = np.gradient(p, 1.0 / rate, axis=0)
    a_world = np.gradient(velocity, 1.0 / rate, axis=0)
    g = np.array([0.0, 0.0, -9.81])
    R_sensor, gyr, acc = {}, {}, {}
    for s in segments:
        true = R_seg[s] @ mounts[s]
        gyr[s] = angular_rate(true, rate)
        noise = exp_so3(rng.normal(scale=np.radians(noise_deg), size=(len(time), 3)))
        R_sensor[s] = true @ noise
        acc[s] = np.einsum("nji,nj->ni", true, a_world - g) if s == "Pelvis" else None
    return SimulatedBody(rate, time, np.radians(heading_deg), {s: R_seg[s] for s in segments},
                         mounts, R_sensor, gyr, {s: a for s, a in acc.items() if a is not None},
                         p)
