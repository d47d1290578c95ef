"""Real motion capture as ground truth: a BVH clip solved into configurations of the model.

The clip's skeleton is mapped onto the 23 segments (:mod:`ikfusion.sim.skeleton_map`), the
body is scaled to the skeleton's proportions, and every frame is solved with the whole-body
solver from the mapped segment orientations and the pelvis position. Contact phases come from
the resulting kinematics (points near the floor and nearly still), so a clip whose feet slide in
the capture keeps that slide in the truth instead of being forced to stand still.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from ..errors import ConfigError
from ..ik.frame import Frame
from ..ik.solver import Solver
from ..io.bvh import read_bvh
from ..model.body import Body
from ..model.human_model import HumanModel
from .skeleton_map import map_motion
from .truth import TruthMotion, contact_phases, site_positions


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


def lead_in(truth: TruthMotion, npose_seconds: float = 2.0,
            transition_seconds: float = 1.0) -> TruthMotion:
    """Prepend a still N-pose and a smooth transition into the first frame.

    A real session starts so; the N-pose faces the first frame's heading at its place on the
    floor.
    """
    model = truth.model
    rate = truth.rate
    first = truth.q[0]
    R0 = model.segment_rotation(first, model.segment_names[0])
    yaw = float(np.arctan2(R0[1, 0], R0[0, 0]))
    q_npose = model.neutral()
    q_npose[:2] = first[:2]
    q_npose[3:7] = pin.Quaternion(pin.utils.rotate("z", yaw)).coeffs()
    n_still = int(round(npose_seconds * rate))
    n_move = int(round(transition_seconds * rate))
    blend = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n_move + 1) / (n_move + 1))
    moving = [pin.interpolate(model.model, q_npose, first, float(a)) for a in blend]
    q = np.vstack([np.repeat(q_npose[None], n_still, axis=0), np.array(moving).reshape(
        -1, len(first)), truth.q])
    time = np.arange(len(q)) / rate
    contacts = contact_phases(model, q, time, truth.contact_names)
    contacts[:n_still] = True
    contacts[n_still + n_move:] = truth.contacts
    return TruthMotion(model, time, q, truth.contact_names, contacts, truth.source,
                       {**truth.info, "lead_in_s": npose_seconds + transition_seconds})


def motion_from_bvh(path: str | Path, rate: float = 60.0,
                    progress: bool = False) -> TruthMotion:
    """Solve a BVH clip into a ground-truth motion of a body scaled to it.

    Args:
        path: The BVH file (any skeleton with named joints, see the skeleton map).
        rate: Output rate [Hz]; the clip is decimated to the nearest integer step.
        progress: Show a progress bar.

    Returns:
        The truth, on the floor (lowest contact point at z = 0), with contact phases.
    """
    bvh = read_bvh(path)
    step = max(1, int(round(bvh.frame_rate / rate)))
    frames = np.arange(0, bvh.num_frames, step)
    mapped = map_motion(bvh, frames=frames)
    body, dropped = body_from_dims(mapped.body_dims)
    model = HumanModel.from_body(body)
    solver = Solver(model, contacts=False, max_iterations=8, step_tolerance=1e-3)
    time = np.arange(len(frames)) * step / bvh.frame_rate
    qs = []
    for k in tqdm(range(len(frames)), disable=not progress, unit="frame", desc="mocap"):
        targets = {s: R[k] for s, R in mapped.R_world_segment.items()}
        frame = Frame(float(time[k]), targets, root_position=mapped.root_position[k],
                      root_position_weight=1e3)
        qs.append(solver.step(frame).q)
    q = np.array(qs)
    contacts = model.sites_of_kind("contact")
    floor = np.percentile(site_positions(model, q, contacts)[..., 2].min(axis=1), 2)
    q[:, 2] -= floor
    phases = contact_phases(model, q, time, contacts)
    return TruthMotion(model, time, q, contacts, phases, str(path), {
        "bvh_rate": bvh.frame_rate, "step": step, "missing_segments": list(mapped.missing),
        "body": body.to_dict(), "dropped_dimensions": dropped})
