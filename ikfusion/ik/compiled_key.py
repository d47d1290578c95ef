"""The structure key of a compiled step function: what its generated code depends on.

Two models with the same key share one compiled library (:mod:`.native`); the geometry (joint
and frame placements) is an input of the functions, not part of the key.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..model.ball_joints import BallJoint
from .compiled_sensed import SensedPoseSpec


def structure_key(model: pin.Model, segment_frames: Sequence[int],
                  ball_joints: Sequence[BallJoint], site_frames: Sequence[int],
                  sensed: SensedPoseSpec | None = None,
                  chain_pairs: Sequence[tuple[BallJoint, BallJoint]] = (),
                  points: Sequence[int] = ()) -> str:
    """A string identifying the compiled structure (not the geometry) of a step function."""
    parts = [
        "objective-v12",
        ",".join(f"{a.idx_q}:{b.idx_q}" for a, b in chain_pairs),
        ",".join(f"{f}:{model.frames[f].parentJoint}" for f in points),
        repr(sensed),
        ",".join(model.joints[j].shortname() for j in range(1, model.njoints)),
        ",".join(str(p) for p in model.parents),
        ",".join(str(model.frames[f].parentJoint) for f in (*segment_frames, *site_frames)),
        ",".join(str(f) for f in (*segment_frames, *site_frames)),
        ",".join(f"{j.idx_q}:{j.spec.sequence}:{j.spec.signs.tolist()}" for j in ball_joints),
    ]
    for j in range(1, model.njoints):
        if model.joints[j].shortname() == "JointModelRevoluteUnaligned":
            parts.append(str(np.round(model.joints[j].extract().axis, 12).tolist()))
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:20]
