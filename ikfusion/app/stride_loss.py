"""The distance a solve loses step by step: the pelvis's travel between the truth's foot strikes.

``drift_percent`` (the pelvis's error at the end over the distance walked) is blind to a stride
that is too short on a closed path: the solved circle is a little smaller than the true one and
closes on itself. Step by step the loss shows wherever the walk goes:

* a **foot strike** is a frame where one of the truth's feet touches down, one of its planted
  points (``<side>Heel``, ``<side>Toe``) on after none of them was for at least
  ``min_swing_s``: the heel strike of a heel-first gait, the toe strike of a toe-first one (a
  foot that lets go for a frame or two, as a motion-capture truth's loose phases do, makes no
  step);
* a **step** runs from one foot strike to the next (of either foot); its true travel is the
  true pelvis's horizontal displacement ``d = p_true[b] - p_true[a]`` [m], its solved travel the
  solved pelvis's displacement over the same frames projected on ``d``'s direction (a solve
  that walks as far but sideways of the truth gains nothing);
* the **stride loss** is ``100 * (1 - sum(solved) / sum(|d|))`` [%] over all steps: positive
  when the solve falls short, negative when it overshoots. Only differences of the pelvis enter,
  so no start alignment is needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The feet and the contact points each plants.
FOOT_POINTS = {"Left": ("LeftHeel", "LeftToe"), "Right": ("RightHeel", "RightToe")}


@dataclass(frozen=True)
class Step:
    """One step of the truth.

    Attributes:
        start: Frame index of the foot strike that begins it.
        end: Frame index of the next foot strike.
        direction: Unit vector (2,) of the true pelvis's horizontal travel (world).
        true_m: The true pelvis's horizontal travel [m].
        solved_m: The solved pelvis's travel along ``direction`` [m].
    """

    start: int
    end: int
    direction: np.ndarray
    true_m: float
    solved_m: float


def foot_strikes(time: np.ndarray, contacts: np.ndarray, names: list[str],
                 min_swing_s: float = 0.1) -> list[int]:
    """Frames where a foot touches down after a swing, both feet, in time order.

    Args:
        time: (N,) sample times [s].
        contacts: (N, k) the truth's contact states (planted: True).
        names: (k,) the contact point names; feet without their points are left out.
        min_swing_s: A foot off the floor for less than this before touching down makes no
            strike [s].
    """
    strikes = []
    for points in FOOT_POINTS.values():
        columns = [names.index(n) for n in points if n in names]
        if not columns:
            continue
        down = [bool(v) for v in np.any(np.asarray(contacts)[:, columns], axis=1)]
        lift = None if down[0] else float(time[0])  # when the foot last left the floor [s]
        for k in range(1, len(down)):
            if down[k - 1] and not down[k]:
                lift = float(time[k])
            elif down[k] and not down[k - 1] and lift is not None:
                if float(time[k]) - lift >= min_swing_s:
                    strikes.append(k)
    return sorted(strikes)


def steps(p_est: np.ndarray, p_true: np.ndarray, strikes: list[int]) -> list[Step]:
    """The steps between consecutive ``strikes`` (frame indices, time order).

    Args:
        p_est: (N, 2+) solved pelvis positions (world) [m]; only x and y are used.
        p_true: (N, 2+) true pelvis positions (world) [m].
        strikes: Frame indices of the foot strikes (:func:`foot_strikes`).
    """
    out = []
    for a, b in zip(strikes[:-1], strikes[1:], strict=True):
        d = p_true[b, :2] - p_true[a, :2]
        length = float(np.linalg.norm(d))
        u = d / max(length, 1e-9)
        out.append(Step(a, b, u, length, float((p_est[b, :2] - p_est[a, :2]) @ u)))
    return out


def stride_loss_percent(step_list: list[Step], min_steps: int = 4,
                        min_distance_m: float = 1.0) -> float | None:
    """How far the solved pelvis falls short of the true one step by step [%] (signed).

    Args:
        step_list: The steps (:func:`steps`).
        min_steps: Fewer steps give no figure (None).
        min_distance_m: Below this true travel summed over the steps the ratio is meaningless
            (None) [m].

    Returns:
        ``100 * (1 - sum of solved travel / sum of true travel)``; None with too few steps or
        too little travel.
    """
    true = sum(s.true_m for s in step_list)
    if len(step_list) < min_steps or true < min_distance_m:
        return None
    return 100.0 * (1.0 - sum(s.solved_m for s in step_list) / true)
