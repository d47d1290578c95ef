"""The still N-pose a simulated clip starts with, and how the actor gets from it into the clip.

A real session starts with the actor standing still in the N-pose; then they walk, lie down or
kneel into the motion's first pose. :func:`lead_in` builds that start so that it is a motion a
person makes, and the IMUs and the solver see nothing a real start would not show:

* The N-pose stands on one foot's place of the pose it leads to (the *anchor* foot, the one
  planted in that pose); during the transition that foot only pivots about its lowest point
  (a heel rising onto the toes), so no planted point slides. The other foot steps: it is
  lifted while it moves.
* A clip that does not start upright (lying, on all fours, mid-cartwheel) is entered by
  getting down: the same poses, longer, but the body always rests on a contact point, held
  where it is: the anchor foot carries it until another point (a knee, a palm) comes down to
  the floor and takes it over (:func:`_rested_on_floor`), so points land, never drag, and the
  body never floats (a pose held above its place, then lowered, left the actor in the air for
  1.5 s: the solver cannot tell, and held points the truth had lifted). Playing the clip
  backwards from a standing moment was tried: it replays the clip's own skating and floor
  errors and doubles its hardest motion.

Contact phases of the lead-in come from its kinematics (points near the floor and nearly still).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..mocap.model_motion import (
    TruthMotion,
    contact_phases,
    limb_contact_sites,
    site_positions,
)
from ..model.human_model import HumanModel
from ..model.layout import TRUNK_CONTACT_SITES

#: A pose stands upright when the pelvis' up axis is within this of vertical [deg] ...
UPRIGHT_TILT_DEG = 30.0
#: ... and the pelvis is at least this fraction of its N-pose height above the floor.
UPRIGHT_HEIGHT = 0.8
#: Joint angles of the stepping leg at the height of its swing [deg]: thigh forward and shank
#: back by the same angle, so the foot rises and lands vertically, level, about 11 cm high.
SWING_ANGLES_DEG = {"Hip_flex": 30.0, "Knee_flex": 60.0, "Ankle_flex": 30.0}
#: Parts of a step: the free foot rises, then the body moves into the pose, then the foot lands.
STEP_LIFT = 0.3
#: Transition into a pose that is not upright (kneeling, on all fours) [s].
GET_DOWN_SECONDS = 2.5
#: The last part of getting down [s] in which the body rises or sinks (vertically) the few
#: centimetres by which its resting points differ from the first pose's height.
GET_DOWN_SETTLE_SECONDS = 0.4
#: A point counts as under the floor, and takes the body over, this far below it [m].
FLOOR_TOLERANCE = 1e-3

_FEET = {"Left": ("LeftHeel", "LeftToe"), "Right": ("RightHeel", "RightToe")}


def is_upright(model: HumanModel, q: np.ndarray) -> bool:
    """Whether a configuration stands upright (:data:`UPRIGHT_TILT_DEG`, :data:`UPRIGHT_HEIGHT`)."""
    R = model.segment_rotation(q, model.segment_names[0])
    return bool(R[2, 2] >= np.cos(np.radians(UPRIGHT_TILT_DEG))
                and q[2] >= UPRIGHT_HEIGHT * model.neutral()[2])


def _cosine_blend(n: int) -> np.ndarray:
    """``n`` values rising smoothly from (not including) 0 to 1, zero slope at both ends."""
    return 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n + 1) / n)


def _yaw_part(R: np.ndarray) -> float:
    """The heading [rad] of the rotation about z closest to ``R``."""
    return float(np.arctan2(R[1, 0] - R[0, 1], R[0, 0] + R[1, 1]))


def _anchor_side(model: HumanModel, q: np.ndarray) -> str:
    """The foot that carries the pose ``q``: the one whose lower point is lower."""
    low = {side: min(model.site_position(q, n)[2] for n in pair) for side, pair in _FEET.items()}
    return min(low, key=lambda s: low[s])


def _pivot(model: HumanModel, q: np.ndarray) -> str:
    """The lower point (heel or toe) of the foot that carries ``q``."""
    return min(_FEET[_anchor_side(model, q)], key=lambda n: model.site_position(q, n)[2])


def _with_swing(model: HumanModel, q: np.ndarray, side: str, weight: float) -> np.ndarray:
    """``q`` with the ``side`` leg bent as in a step's swing, by ``weight`` in [0, 1]."""
    bend = model.configuration({f"j{side}{k}": weight * v for k, v in SWING_ANGLES_DEG.items()})
    out = q.copy()
    for name in (f"j{side}Hip", f"j{side}Knee", f"j{side}Ankle"):
        i = model.ball_joint(name).idx_q
        R = pin.Quaternion(q[i:i + 4]).matrix() @ pin.Quaternion(bend[i:i + 4]).matrix()
        out[i:i + 4] = pin.Quaternion(R).coeffs()
    return out


def anchored_transition(model: HumanModel, target: np.ndarray, n_still: int, n_move: int
                        ) -> np.ndarray:
    """The N-pose held still, then a step into ``target``: configurations (n_still + n_move, nq).

    The anchor foot (:func:`_anchor_side`) keeps its lowest point of ``target`` fixed on the
    floor (lifted vertically only if that point is above the floor in ``target``) and its
    heading; it pivots about that point from flat to its pose in ``target``. Joint angles blend
    from zero (the N-pose) to ``target``'s, the pelvis follows from the anchored foot, the other
    leg swings (:data:`SWING_ANGLES_DEG`). Where a contact point would go under the floor, the
    whole body is lifted. The last configuration is ``target``.
    """
    side = _anchor_side(model, target)
    foot = f"{side}Foot"
    pivot = _pivot(model, target)
    other = "Right" if side == "Left" else "Left"
    R_end = model.segment_rotation(target, foot)
    R_neutral = model.segment_rotation(model.neutral(), foot)
    R_start = pin.utils.rotate("z", _yaw_part(R_end @ R_neutral.T)) @ R_neutral
    p_pivot = model.site_position(target, pivot)
    turn = pin.log3(R_start.T @ R_end)
    q_from = model.neutral()
    q_from[:7] = target[:7]  # joints blend alone: the root is placed from the anchor
    t = np.arange(1, n_move + 1) / n_move
    lift = np.clip(np.minimum(t, 1.0 - t) / STEP_LIFT, 0.0, 1.0)
    move = np.clip((t - STEP_LIFT) / (1.0 - 2.0 * STEP_LIFT), 0.0, 1.0)
    blend = np.concatenate([np.zeros(n_still), 0.5 - 0.5 * np.cos(np.pi * move)])
    swing = np.concatenate([np.zeros(n_still), 0.5 - 0.5 * np.cos(np.pi * lift)])
    origin = np.zeros(model.model.nq)
    out = np.empty((len(blend), model.model.nq))
    for k, (a, w) in enumerate(zip(blend, swing, strict=True)):
        joints = _with_swing(model, pin.interpolate(model.model, q_from, target, float(a)),
                             other, float(w))
        origin[7:] = joints[7:]
        origin[3:7] = [0.0, 0.0, 0.0, 1.0]
        R_world_foot = R_start @ pin.exp3(a * turn)
        R_world_root = R_world_foot @ model.segment_rotation(origin, foot).T
        p_world_pivot = np.array([p_pivot[0], p_pivot[1], a * p_pivot[2]])
        qk = joints.copy()
        qk[3:7] = pin.Quaternion(R_world_root).coeffs()
        qk[:3] = p_world_pivot - R_world_root @ model.site_position(origin, pivot)
        out[k] = qk
    out = _above_floor(model, out)
    out[-1] = target
    return out


def _above_floor(model: HumanModel, q: np.ndarray) -> np.ndarray:
    """Configurations (N, nq) lifted where a limb's contact point is under the floor (z < 0)."""
    low = site_positions(model, q, limb_contact_sites(model))[..., 2].min(axis=1)
    out = q.copy()
    out[:, 2] += np.maximum(0.0, -low)
    return out


def _rested_on_floor(model: HumanModel, q: np.ndarray, support: str, n_settle: int
                     ) -> np.ndarray:
    """Configurations (N, nq) moved so that the body always rests on one point.

    Each frame keeps the pose and orientation of ``q``; its translation holds the supporting
    point (first the site ``support``) where it was. When another site (contact points, but
    also the pelvis or back of a body lying down) would go more than
    :data:`FLOOR_TOLERANCE` under the floor, the body rises onto it and that point carries it from
    then on (a knee coming down takes the body over from the foot, which lifts): no point
    drags, none goes under the floor, and the body is never in the air. The whole is then
    shifted horizontally to end where the last of ``q`` is, and in the last ``n_settle``
    frames it rises or sinks vertically towards it, kept above the floor (the clip's first
    pose may have a point under it). Returns all but the last configuration: ``q[-1]`` is the
    clip's first frame, which follows.
    """
    # a lying body rests on its back (the sensor sites there), not on a contact point; the
    # model's guessed trunk surface (limb_contact_sites) shapes no truth
    names = [n for n in model.site_names if n not in TRUNK_CONTACT_SITES]
    P = site_positions(model, q, names)
    k = names.index(support)
    held = P[0, k] * [1.0, 1.0, 0.0]
    out = q.copy()
    for i in range(len(q)):
        shift = held - P[i, k]
        z = P[i, :, 2] + shift[2]
        j = int(np.argmin(z))
        if z[j] < -FLOOR_TOLERANCE:
            shift[2] -= z[j]
            k, held = j, P[i, j] + shift
        out[i, :3] += shift
    end = q[-1, :3] - out[-1, :3]
    out[:, :2] += end[:2]
    n = max(1, min(n_settle, len(q)))
    out[-n:, 2] += end[2] * _cosine_blend(n)
    return _above_floor(model, out[:-1])


def lead_in(truth: TruthMotion, npose_seconds: float = 2.0,
            transition_seconds: float = 1.5) -> TruthMotion:
    """Prepend a still N-pose and a way a person gets from it into the clip's first frame.

    See the module's docstring for the two cases (upright start or not). The clip itself is
    kept unchanged after the lead-in.

    Args:
        truth: The clip, floor at z = 0.
        npose_seconds: Still N-pose [s].
        transition_seconds: The step from the N-pose into an upright pose [s]; a pose that is
            not upright takes :data:`GET_DOWN_SECONDS`.

    Returns:
        The motion with the lead-in; ``info["lead_in_s"]`` is its length [s] and
        ``info["lead_in"]`` says how it enters the clip (``"step"`` or ``"get-down"``).
    """
    model, rate = truth.model, truth.rate
    n_still = int(round(npose_seconds * rate))
    first = truth.q[0]
    if is_upright(model, first):
        kind = "step"
        parts = [anchored_transition(model, first, n_still,
                                     max(2, int(round(transition_seconds * rate))))]
    else:
        kind = "get-down"
        n_move = max(2, int(round(GET_DOWN_SECONDS * rate)))
        parts = [_rested_on_floor(model, anchored_transition(model, first, n_still, n_move),
                                  _pivot(model, first),
                                  int(round(GET_DOWN_SETTLE_SECONDS * rate)))]
    lead = np.vstack(parts)
    q = np.vstack([lead, truth.q])
    time = np.arange(len(q)) / rate
    contacts = np.vstack([contact_phases(model, q[:len(lead) + 1], time[:len(lead) + 1],
                                         truth.contact_names)[:-1], truth.contacts])
    return TruthMotion(model, time, q, truth.contact_names, contacts, truth.source,
                       {**truth.info, "lead_in_s": len(lead) / rate, "lead_in": kind})
