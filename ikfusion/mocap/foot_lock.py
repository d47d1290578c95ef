"""Planted contact points that hold still: a root correction for motion read from mocap.

A BVH clip solved onto our model keeps the clip's root track while the legs and feet are ours
(other bone lengths, another foot), so its feet skate by a few centimetres per step although the
captured person's did not. :func:`lock_planted_points` shifts the root horizontally, frame by
frame, so that the points in contact stay where they landed; joint angles and orientations are
left exactly as they are.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_banded

from ..model.human_model import HumanModel
from ..model.motion_kinematics import JointRotations
from .model_motion import contact_phases_from_points, site_positions

#: How quickly the root correction's velocity may change [s]: a touchdown's correction is
#: blended in over about this time (a heel strike's duration) instead of in one frame, which
#: would put an acceleration spike into the simulated IMUs.
LOCK_BLEND_S = 0.05
#: Weight (relative to a planted point's) that pulls the correction velocity back to zero while
#: points are planted (they then hold within 1 % of their skating) ...
LOCK_RELAX = 0.01
#: ... and while none is (flight, a clip with no stance): the correction then fades out within
#: about ``LOCK_BLEND_S`` and the captured root motion is kept (a jump's flight stays ballistic).
LOCK_RELAX_FREE = 1.0
#: Passes of label - correct: the contact phases are labelled again on the corrected motion
#: (points that stopped skating are now slow enough to count as planted).
LOCK_PASSES = 3


def planted_velocity_correction(P: np.ndarray, time: np.ndarray, planted: np.ndarray,
                                blend_s: float = LOCK_BLEND_S,
                                relax: float = LOCK_RELAX,
                                relax_free: float = LOCK_RELAX_FREE) -> np.ndarray:
    """The horizontal root velocity correction [m/s] that holds planted points still.

    Args:
        P: Contact points' world positions (N, k, 3) [m].
        time: (N,) [s].
        planted: (N, k) contact phases; a point counts in a step when planted at both ends
            and in the steps before and after (not in a phase's first and last step).
        blend_s: Time over which the correction's velocity may change [s].
        rotations: The joints' rotations along ``q`` kept between queries
            (:class:`~ikfusion.model.motion_kinematics.JointRotations`; the same result without).
        relax: Pull of the correction toward zero (relative weight per step) ...
        relax_free: ... and in steps without a planted point.

    Returns:
        (N - 1, 2) velocity added to the root over each step [m/s]: the least-squares
        compromise between the planted points' horizontal velocities (zero when they agree),
        a smooth correction and no correction; all zero when no point is planted or the
        planted points already hold still.
    """
    dt = np.diff(time)
    v = np.diff(P[..., :2], axis=0) / dt[:, None, None]  # (M, k, 2)
    held = planted[1:] & planted[:-1]
    # a touchdown's or lift-off's step is left out: the point may still be arriving or leaving
    held = held & np.vstack([held[1:], held[-1:]]) & np.vstack([held[:1], held[:-1]])
    w = held.astype(float)  # (M, k)
    m = len(dt)
    smooth = (blend_s / float(np.mean(dt))) ** 2
    diag = w.sum(axis=1) + np.where(w.any(axis=1), relax, relax_free)
    ab = np.zeros((3, m))
    ab[1] = diag
    if m > 1:
        ab[1, :-1] += smooth
        ab[1, 1:] += smooth
        ab[0, 1:] = -smooth
        ab[2, :-1] = -smooth
    rhs = -np.einsum("mk,mkc->mc", w, v)
    return solve_banded((1, 1), ab, rhs)


def lock_planted_points(model: HumanModel, q: np.ndarray, time: np.ndarray,
                        names: list[str], height: float = 0.03,
                        speed: float = 0.3,
                        blend_s: float = LOCK_BLEND_S, rotations: JointRotations | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Configurations whose planted contact points do not slide horizontally.

    The contact phases are labelled (:func:`~ikfusion.mocap.model_motion.contact_phases`,
    ``height`` [m], ``speed`` [m/s]); the root then gets the horizontal offset whose velocity
    cancels the planted points' mean horizontal velocity, blended smoothly over
    :data:`LOCK_BLEND_S` at phase changes and fading out without a planted point
    (:func:`planted_velocity_correction`); the phases are labelled again on the result
    (:data:`LOCK_PASSES` passes). Only the root's x and y change: orientations, joint angles
    and heights are kept, and a motion whose planted points already hold still is unchanged.

    Args:
        model: The human model ``q`` moves.
        q: (N, nq) configurations, floor at z = 0.
        time: (N,) [s].
        names: Contact sites.
        height: A contact point below this is near the floor [m] ...
        speed: ... and planted when slower than this [m/s].
        blend_s: Time over which the correction's velocity may change [s].
        rotations: The joints' rotations along ``q`` kept between queries
            (:class:`~ikfusion.model.motion_kinematics.JointRotations`; the same result without).

    Returns:
        The corrected configurations (N, nq) and the root offset added (N, 2) [m] (zero at
        the first frame).
    """
    if len(time) < 3 or not names:
        return q.copy(), np.zeros((len(time), 2))
    P = site_positions(model, q, names, rotations)
    offset = np.zeros((len(time), 2))
    for _ in range(LOCK_PASSES):
        moved = P.copy()
        moved[..., :2] += offset[:, None, :]
        planted = contact_phases_from_points(moved, time, height, speed)
        u = planted_velocity_correction(P, time, planted, blend_s)
        new = np.vstack([np.zeros((1, 2)), np.cumsum(u * np.diff(time)[:, None], axis=0)])
        if np.allclose(new, offset, atol=1e-6):
            break
        offset = new
    out = q.copy()
    out[:, :2] += offset
    return out, offset
