"""Ground truth of a simulated capture, and its ``truth.npz`` file (SPEC section 5)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..atomic import atomic_write
from ..errors import InputError
from ..ik.frame import Frame
from ..imu.stance import foot_still
from ..io.npz import read_npz
from ..model.human_model import HumanModel
from ..rotations import matrix_to_quat_wxyz


@dataclass
class TruthMotion:
    """A motion of the model that simulated sensors are computed from.

    Attributes:
        model: The human model it moves.
        time: (N,) [s].
        q: (N, nq) configurations.
        contact_names: Contact points (columns of ``contacts``).
        contacts: (N, k) true contact phases.
        source: Where it came from (``gait:circle``, a BVH path, ...).
        info: Anything else worth keeping (gait parameters, BVH mapping notes).
    """

    model: HumanModel
    time: np.ndarray
    q: np.ndarray
    contact_names: list[str]
    contacts: np.ndarray
    source: str = ""
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def rate(self) -> float:
        """Sample rate [Hz]."""
        return float(1.0 / np.mean(np.diff(self.time))) if len(self.time) > 1 else 0.0


def moved_configurations(q: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Configurations (N, nq) of a free-flyer model moved rigidly: ``p -> R p + t``.

    The root position and orientation turn by ``R`` (3, 3) and shift by ``t`` (3,) [m];
    joint coordinates are unchanged.
    """
    out = q.copy()
    out[:, :3] = q[:, :3] @ np.asarray(R).T + np.asarray(t)
    for k in range(len(q)):
        out[k, 3:7] = pin.Quaternion(R @ pin.Quaternion(q[k, 3:7]).matrix()).coeffs()
    return out


def contact_phases(model: HumanModel, q: np.ndarray, time: np.ndarray,
                   names: list[str], height: float = 0.03, speed: float = 0.3) -> np.ndarray:
    """Contact phases from kinematics: a point near the floor (z = 0) that is nearly still."""
    return contact_phases_from_points(site_positions(model, q, names), time, height, speed)


def contact_phases_from_points(P: np.ndarray, time: np.ndarray, height: float = 0.03,
                               speed: float = 0.3) -> np.ndarray:
    """(N, k) contact phases of points (N, k, 3) [m].

    A point is in contact below ``height`` [m] and slower than ``speed`` [m/s].
    """
    if len(time) < 2:
        return P[..., 2] < height
    v = np.linalg.norm(np.gradient(P, float(np.mean(np.diff(time))), axis=0), axis=2)
    return (P[..., 2] < height) & (v < speed)


def segment_poses(model: HumanModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every segment's world origin (N, S, 3) [m] and rotation (N, S, 3, 3) along ``q``.

    Segments in ``model.segment_names`` order; ``q`` is (N, nq).
    """
    data = model.model.createData()
    ids = [model.segment_frame_id(s) for s in model.segment_names]
    p = np.empty((len(q), len(ids), 3))
    R = np.empty((len(q), len(ids), 3, 3))
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(model.model, data, qk)
        for i, f in enumerate(ids):
            p[k, i], R[k, i] = data.oMf[f].translation, data.oMf[f].rotation
    return p, R


def site_positions(model: HumanModel, q: np.ndarray, names: list[str]) -> np.ndarray:
    """World positions (N, k, 3) [m] of sites along configurations (N, nq)."""
    data = model.model.createData()
    ids = [model.site_frame_id(n) for n in names]
    out = np.empty((len(q), len(ids), 3))
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(model.model, data, qk)
        for i, f in enumerate(ids):
            out[k, i] = data.oMf[f].translation
    return out


def orientation_frames(model: HumanModel, q: np.ndarray, time: np.ndarray,
                       segments: list[str] | tuple[str, ...]) -> list[Frame]:
    """Solver frames whose targets are the exact segment orientations along ``q`` (N, nq)."""
    data = model.model.createData()
    ids = [model.segment_frame_id(s) for s in segments]
    frames = []
    for t, qk in zip(time, q):
        pin.framesForwardKinematics(model.model, data, qk)
        frames.append(Frame(float(t), {s: data.oMf[f].rotation.copy()
                                       for s, f in zip(segments, ids)}))
    return frames


def write_truth(path: str | Path, truth: TruthMotion) -> Path:
    """Write ``truth.npz``: time, q, segment poses, site positions and contact phases.

    Keys: ``time`` (N,) [s]; ``q`` (N, nq); ``segment_names``; ``p_world_segment`` (N, S, 3)
    [m]; ``quat_wxyz_world_segment`` (N, S, 4); ``site_names``; ``p_world_site`` (N, M, 3) [m];
    ``contact_names``; ``contacts`` (N, k) bool; ``joint_angle_names`` and ``joint_angles``
    (N, 66) [deg]; ``source``; with ``info["area_fit"]`` (where ``simulate --readers`` put
    the motion in the capture area, see :mod:`ikfusion.sim.area_fit`) also ``area_fit``, that
    mapping as a JSON string.
    """
    model = truth.model
    segments = model.segment_names
    sites = model.site_names
    p_seg, R_seg = segment_poses(model, truth.q)
    extra: dict[str, Any] = {}
    if "area_fit" in truth.info:
        extra["area_fit"] = np.array(json.dumps(truth.info["area_fit"]))
    with atomic_write(path, "wb") as out:
        np.savez_compressed(
            out, time=truth.time, q=truth.q, segment_names=np.array(segments),
            p_world_segment=p_seg, quat_wxyz_world_segment=matrix_to_quat_wxyz(R_seg),
            site_names=np.array(sites), p_world_site=site_positions(model, truth.q, sites),
            contact_names=np.array(truth.contact_names), contacts=truth.contacts,
            joint_angle_names=np.array(model.angle_columns),
            joint_angles=model.joint_angle_matrix(truth.q), source=np.array(truth.source),
            **extra)
    return Path(path)


#: The arrays of ``truth.npz`` with their shapes (names of sizes: N frames, S segments, M
#: sites, C contacts, J joint-angle columns; integers are fixed sizes).
TRUTH_SHAPES: dict[str, tuple[str | int, ...]] = {
    "time": ("N",), "segment_names": ("S",), "p_world_segment": ("N", "S", 3),
    "quat_wxyz_world_segment": ("N", "S", 4), "site_names": ("M",),
    "p_world_site": ("N", "M", 3), "contact_names": ("C",), "contacts": ("N", "C"),
    "joint_angle_names": ("J",), "joint_angles": ("N", "J"),
}


def read_truth(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a ``truth.npz`` (see :func:`write_truth`), checked.

    Raises:
        InputError: A damaged file, a missing array, shapes that do not agree, times that do
            not increase, or non-finite values (file and array named).
    """
    data = read_npz(path, TRUTH_SHAPES, "truth.npz")
    sizes: dict[str, int] = {}
    for name, shape in TRUTH_SHAPES.items():
        array = data[name]
        if array.ndim != len(shape) or any(
                isinstance(d, int) and array.shape[k] != d for k, d in enumerate(shape)):
            raise InputError(f"expected shape ({', '.join(map(str, shape))}), found "
                             f"{array.shape}", path=path, field=name)
        for k, d in enumerate(shape):
            if isinstance(d, str) and sizes.setdefault(d, array.shape[k]) != array.shape[k]:
                raise InputError(f"{d} = {array.shape[k]} along axis {k} disagrees with "
                                 f"{sizes[d]} in the other arrays", path=path, field=name)
        if array.dtype.kind in "fiub" and not np.isfinite(array.astype(float)).all():
            raise InputError("non-finite values", path=path, field=name)
    if sizes["N"] < 2 or not (np.diff(data["time"].astype(float)) > 0).all():
        raise InputError("expected at least two frames with increasing times", path=path,
                         field="time")
    return data


def with_feet_still(frames: list[Frame], rate: float) -> list[Frame]:
    """The frames with the feet's stance added.

    Stance comes from the feet's orientations (:func:`ikfusion.imu.stance.foot_still`), as the
    pipeline finds it from foot IMUs.
    """
    out = list(frames)
    for foot in ("LeftFoot", "RightFoot"):
        R = np.array([f.orientations.get(foot, np.full((3, 3), np.nan)) for f in frames])
        still = foot_still(R, rate)
        out = [replace(f, feet_still={**f.feet_still, foot: bool(s)}) if np.isfinite(s) else f
               for f, s in zip(out, still)]
    return out
