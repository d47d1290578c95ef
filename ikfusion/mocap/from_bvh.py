"""A BVH clip solved into configurations of the model (real motion capture as a motion).

The clip's skeleton is mapped onto the 23 segments (:mod:`ikfusion.mocap.skeleton_map`), the
body is scaled to the skeleton's proportions, and every frame is solved with the whole-body
solver from the mapped segment orientations and the pelvis position. Mocap clips skate (by 1-3
cm per step on CMU's; the BVH skeleton's own ankles slide as much as ours), which a real body
does not: the root is then shifted horizontally so that planted contact points hold still
(:mod:`ikfusion.mocap.foot_lock`), and contact phases come from the result's kinematics (points
near the floor and nearly still). Our hands and feet are not the clip's either: where one would go
under the floor the body is lifted out of it (:func:`floor_lift`).
"""

from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.ndimage import maximum_filter1d, uniform_filter1d
from tqdm import tqdm

from ..errors import ConfigError
from ..ik.frame import Frame
from ..ik.solver import Solver
from ..io.bvh import read_bvh
from ..model.body import Body
from ..model.human_model import HumanModel
from ..model.motion_kinematics import JointRotations
from ..rotations import angle_between
from .direct_pose import configurations_from_orientations
from .foot_lock import lock_planted_points
from .model_motion import (
    TruthMotion,
    contact_phases_from_points,
    frame_poses,
    limb_contact_sites,
    moved_configurations,
    site_positions,
)
from .skeleton_map import MappedMotion, map_motion


def body_from_dims(dims: dict[str, float]) -> tuple[Body, list[str]]:
    """A valid :class:`Body` from estimated dimensions, dropping the implausible ones.

    Returns:
        The body and the names of the dimensions that were dropped (height-based defaults).
    """
    known = {f.name for f in fields(Body)}
    kept = {k: float(v) for k, v in dims.items() if k in known and np.isfinite(v)}
    dropped: list[str] = []
    while True:
        try:
            return Body.from_dict(kept), dropped
        except ConfigError as err:
            if err.field is None or err.field not in kept or err.field == "height":
                raise
            dropped.append(err.field)
            kept.pop(err.field)


#: Lowest contact points slower than this stand on the floor [m/s] ...
FLOOR_SPEED = 0.25
#: ... unless this far above the floor plane fitted to them [m].
FLOOR_OUTLIER = 0.02
#: A fitted floor steeper than this is not trusted (the floor is then taken level) [deg].
FLOOR_MAX_TILT_DEG = 5.0


def floor_plane(points: np.ndarray, time: np.ndarray) -> tuple[np.ndarray, float]:
    """The floor under a motion: unit normal (3,) and height along it [m].

    Args:
        points: Contact points' world positions (N, k, 3) [m].
        time: (N,) [s].

    Each frame's lowest point, when nearly still, stands on the floor; a plane is fitted to
    those by least squares, twice dropping points far above it (a foot resting on something).
    Mocap halls are not always level with their capture volume (CMU clips rise by 2 %).
    Without enough standing points spread over a metre, the floor is level at the height of
    the lowest points.
    """
    dt = float(np.mean(np.diff(time))) if len(time) > 1 else 1.0
    speed = np.linalg.norm(np.gradient(points, dt, axis=0), axis=2) if len(time) > 1 \
        else np.zeros(points.shape[:2])
    low = points[np.arange(len(points)), points[..., 2].argmin(axis=1)]
    slow = speed[np.arange(len(points)), points[..., 2].argmin(axis=1)] < FLOOR_SPEED
    level = np.array([0.0, 0.0, 1.0])
    fallback = float(np.percentile(low[:, 2], 2))
    sample = low[slow]
    if len(sample) < 20 or np.ptp(sample[:, :2], axis=0).max() < 1.0:
        return level, fallback if len(sample) < 5 else float(np.median(sample[:, 2]))
    keep = np.ones(len(sample), dtype=bool)
    for _ in range(3):
        A = np.column_stack([np.ones(keep.sum()), sample[keep, :2]])
        coef = np.linalg.lstsq(A, sample[keep, 2], rcond=None)[0]
        residual = sample[:, 2] - (coef[0] + sample[:, :2] @ coef[1:])
        keep = residual < FLOOR_OUTLIER
        if keep.sum() < 10:
            return level, fallback
    normal = np.array([-coef[1], -coef[2], 1.0])
    normal /= np.linalg.norm(normal)
    if np.degrees(np.arccos(normal[2])) > FLOOR_MAX_TILT_DEG:
        return level, float(np.median(sample[:, 2]))
    return normal, float(coef[0] * normal[2])


def level_on_floor(q: np.ndarray, points: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Configurations (N, nq) turned and lifted so the floor (:func:`floor_plane`) is z = 0."""
    normal, height = floor_plane(points, time)
    axis = np.cross(normal, [0.0, 0.0, 1.0])
    angle = np.arcsin(min(1.0, float(np.linalg.norm(axis))))
    R = pin.exp3(axis / np.linalg.norm(axis) * angle) if angle > 1e-9 else np.eye(3)
    return moved_configurations(q, R, np.array([0.0, 0.0, -height]))


#: A lift out of the floor is blended in and out over about this time [s] (the lowest point's
#: depth changes slope where another point becomes the lowest: lifting by it exactly would put
#: acceleration spikes into the simulated IMUs).
FLOOR_LIFT_BLEND_S = 0.2


def floor_lift(points: np.ndarray, time: np.ndarray, blend_s: float = FLOOR_LIFT_BLEND_S,
               tolerance: float = FLOOR_OUTLIER) -> np.ndarray:
    """The smooth vertical lift (N,) [m] that keeps every point at most ``tolerance`` under z = 0.

    A clip read onto a body of other proportions (longer hands, another foot) puts points
    under the floor that the captured person had on it: a cartwheel's palms went 19 cm deep,
    which no solver holding them on the floor can follow (the whole body 15 cm too high in the
    truth's terms). Within ``tolerance`` [m] a point is left as it is: the floor is fitted
    through the standing points (:func:`floor_plane`), so their scatter puts some of them a
    little under it. The lift is the least one that covers each frame's depth beyond that:
    the excess's running maximum over ``blend_s`` [s], averaged over ``blend_s`` (so it never
    falls below the excess, and its velocity is continuous); zero where nothing is deeper.

    Args:
        points: Contact points' world positions (N, k, 3) [m], floor at z = 0.
        time: (N,) [s].
        blend_s: Time over which the lift rises and falls [s].
        tolerance: Depth left alone [m].
    """
    if points.size == 0:
        return np.zeros(len(time))
    excess = np.maximum(0.0, -points[..., 2].min(axis=1) - tolerance)
    if not excess.any() or len(time) < 2:
        return excess
    width = max(1, int(round(blend_s / float(np.mean(np.diff(time)))))) | 1  # odd: centred
    envelope = maximum_filter1d(excess, width, mode="nearest")
    return np.maximum(uniform_filter1d(envelope, width, mode="nearest"), excess)


#: A first frame whose segments turn more than this before the next one [deg] is a reference
#: pose (CMU's clips start with one), not motion: it is dropped.
REFERENCE_FRAME_JUMP_DEG = 90.0


def _starts_with_reference_pose(R_world_segment: dict[str, np.ndarray]) -> bool:
    """Whether a segment turns more than :data:`REFERENCE_FRAME_JUMP_DEG` in the first step."""
    return any(np.degrees(angle_between(R[0], R[1])) > REFERENCE_FRAME_JUMP_DEG
               for R in R_world_segment.values())


def _without_first_frame(mapped: MappedMotion) -> MappedMotion:
    """The mapped motion from its second frame on (the skeleton map does not depend on it)."""
    return replace(mapped, time=mapped.time[1:],
                   R_world_segment={s: R[1:] for s, R in mapped.R_world_segment.items()},
                   p_world_joint={j: p[1:] for j, p in mapped.p_world_joint.items()},
                   root_position=mapped.root_position[1:])


def motion_from_bvh(path: str | Path, rate: float = 60.0, progress: bool = False,
                    lock_contacts: bool = True, direct: bool = False) -> TruthMotion:
    """Solve a BVH clip into a ground-truth motion of a body scaled to it.

    Args:
        path: The BVH file (any skeleton with named joints, see the skeleton map).
        rate: Output rate [Hz]; the clip is decimated to the nearest integer step.
        progress: Show a progress bar.
        lock_contacts: Shift the root horizontally so planted contact points do not skate
            (:func:`~ikfusion.mocap.foot_lock.lock_planted_points`; orientations, joint angles
            and heights are kept, a clip without skating or without stance is unchanged).
        direct: Put the mapped orientations onto the joints in closed form, held inside the
            ranges of motion (:mod:`~ikfusion.mocap.direct_pose`), instead of solving every
            frame; tens of times faster, the same pose wherever no range binds.

    Returns:
        The truth, on the floor (lowest contact point at z = 0) and never deeper under it than
        the floor fit's scatter (lifted where a point of our body went under the floor,
        :func:`floor_lift`), with contact phases; ``info["warnings"]`` lists the bad samples
        the reader bridged,
        ``info["lock_offset_max_m"]`` the largest root shift of the lock [m],
        ``info["floor_lift_max_m"]`` the largest lift out of the floor [m].

    Raises:
        InputError: A malformed file, or bad samples that cannot be bridged (file, line,
            channel).
    """
    return _bvh_motion(path, rate, progress, lock_contacts, direct, segments=False)[0]


def segment_motion_from_bvh(path: str | Path) -> tuple[TruthMotion, np.ndarray, np.ndarray]:
    """:func:`motion_from_bvh` (``direct=True``) and every segment's world pose along it.

    Returns:
        The truth, and the origins (N, S, 3) [m] and rotations ``R_world_segment``
        (N, S, 3, 3) of the segments in ``model.segment_names`` order, from the kinematics
        pass that also gives the contact phases.

    Raises:
        InputError: As :func:`motion_from_bvh`.
    """
    truth, poses = _bvh_motion(path, 60.0, False, True, True, segments=True)
    return truth, *poses


def _bvh_motion(path: str | Path, rate: float, progress: bool, lock_contacts: bool,
                direct: bool, segments: bool
                ) -> tuple[TruthMotion, tuple[np.ndarray, np.ndarray]]:
    """:func:`motion_from_bvh`, and with ``segments`` the segments' origins and rotations."""
    bvh = read_bvh(path)
    step = max(1, int(round(bvh.frame_rate / rate)))
    frames = np.arange(0, bvh.num_frames, step)
    mapped = map_motion(bvh, frames=frames)
    if len(frames) > 2 and _starts_with_reference_pose(mapped.R_world_segment):
        frames = frames[1:]
        mapped = _without_first_frame(mapped)
    body, dropped = body_from_dims(mapped.body_dims)
    model = HumanModel.from_body(body)
    time = np.arange(len(frames)) * step / bvh.frame_rate
    if direct:
        q, _ = configurations_from_orientations(model, mapped.R_world_segment,
                                                mapped.root_position)
    else:
        q = _solved_configurations(model, mapped, time, progress)
    contacts = model.sites_of_kind("contact")  # all labelled, the floor from the limbs'
    limbs = limb_contact_sites(model)
    q = level_on_floor(q, site_positions(model, q, limbs), time)
    # from here on only the root's position moves: its joints' rotations are computed once
    rotations = JointRotations()
    offset = np.zeros((len(time), 2))
    if lock_contacts:  # before the lift: the clip's standing points, not those it lifted
        q, offset = lock_planted_points(model, q, time, limbs, rotations=rotations)
    lift = floor_lift(site_positions(model, q, limbs, rotations), time)
    q[:, 2] += lift
    segment_ids = [model.segment_frame_id(s) for s in model.segment_names] if segments else []
    p, R = frame_poses(model.model, q, [*(model.site_frame_id(n) for n in contacts),
                                        *segment_ids], rotations)
    phases = contact_phases_from_points(p[:, :len(contacts)], time)
    truth = TruthMotion(model, time, q, contacts, phases, str(path), {
        "bvh_rate": bvh.frame_rate, "step": step, "missing_segments": list(mapped.missing),
        "body": body.to_dict(), "dropped_dimensions": dropped,
        "warnings": list(bvh.warnings),
        "lock_offset_max_m": float(np.linalg.norm(offset, axis=1).max(initial=0.0)),
        "floor_lift_max_m": float(lift.max(initial=0.0))})
    return truth, (p[:, len(contacts):], R[:, len(contacts):])


def _solved_configurations(model: HumanModel, mapped: MappedMotion, time: np.ndarray,
                           progress: bool) -> np.ndarray:
    """Configurations (N, nq) solved frame by frame from the mapped orientations and root."""
    solver = Solver(model, contacts=False, max_iterations=8, step_tolerance=1e-3,
                    joint_range_overshoot_deg=0.0)  # a truth stays inside its ranges
    qs = []
    for k in tqdm(range(len(time)), disable=not progress, unit="frame", desc="mocap"):
        targets = {s: R[k] for s, R in mapped.R_world_segment.items()}
        frame = Frame(float(time[k]), targets, root_position=mapped.root_position[k],
                      root_position_weight=1e3)
        qs.append(solver.step(frame).q)
    return np.array(qs)
