"""Orientation targets for unsensed segments that a hinge joint decides (reduced sensor sets).

A thigh without a sensor between a sensed pelvis and a sensed shank (or an upper arm between a
sensed trunk or shoulder and a sensed forearm) leaves one rotation open: how the pelvis-to-shank
rotation is shared between hip and knee. The posture prior alone leaves that share to whatever
else pulls (contacts, pelvis continuity), and the thighs wander into a crouch. Here the open
segment gets the orientation of the plausible default instead: the knee (elbow) is a pure hinge,
bent within its range of motion, and the thigh (upper arm) turns as little as possible from its
nearest sensed ancestor (in the N-pose every segment is parallel to it):

    R_world_X = R_world_C @ R(a, k)^T,   k = argmax_k trace(R_world_P^T R_world_X)

with ``R(a, k)`` the hinge's flexion rotation (axis ``a`` = its flexion axis times sign, from
``configs/joints.yaml``), ``C`` the sensed child and ``P`` the sensed ancestor. The maximum has
a closed form, ``A cos(theta) + B sin(theta)`` in the hinge rotation ``theta``. The target agrees
with every measured orientation (pelvis, shank and knee all fit it exactly), so a modest weight
never fights a sensor; it only decides what the sensors leave open.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..rotations import axis_rotation

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class _Hinge:
    """A hinge joint: its open (parent) segment, sensed child, flexion axis and range."""

    joint: str
    segment: int        # index of the joint's parent segment (thigh, upper arm)
    child: int          # index of the child segment (shank, forearm)
    ancestors: tuple[int, ...]  # the segment's ancestors, nearest first
    axis: str
    sign: int
    lower: float        # [rad], hyperextension excluded (>= 0)
    upper: float        # [rad]


class AssumedTargets:
    """Orientation targets for unsensed segments above a sensed hinge child.

    Args:
        segments: Segment names in the solver's order.
        joints: ``HumanModel.ball_joints`` (name -> joint with ``spec``).
        hinges: Names of the joints treated as hinges (knees, elbows).

    Raises:
        ConfigError: A hinge that is not a joint of the model.
    """

    def __init__(self, segments: Sequence[str], joints: Mapping[str, object],
                 hinges: Sequence[str]) -> None:
        index = {n: i for i, n in enumerate(segments)}
        parent_of: dict[int, int] = {}
        for joint in joints.values():
            spec = joint.spec  # type: ignore[attr-defined]
            parent_of[index[spec.child]] = index[spec.parent]
        self.hinges: list[_Hinge] = []
        for name in hinges:
            if name not in joints:
                raise ConfigError(f"unknown joint {name!r}; joints: {', '.join(joints)}",
                                  field="hinge_joints")
            spec = joints[name].spec  # type: ignore[attr-defined]
            flex = spec.angles[0]
            segment = index[spec.parent]
            chain = []
            k = segment
            while k in parent_of:
                k = parent_of[k]
                chain.append(k)
            self.hinges.append(_Hinge(name, segment, index[spec.child], tuple(chain),
                                      flex.axis, int(flex.sign),
                                      float(np.radians(max(flex.lower_deg, 0.0))),
                                      float(np.radians(flex.upper_deg))))

    def any_open(self, sensed: np.ndarray) -> bool:
        """Whether :meth:`targets` gives a target with these ``sensed`` (n,) segments."""
        return any(not sensed[h.segment] and sensed[h.child]
                   and any(sensed[a] for a in h.ancestors) for h in self.hinges)

    def targets(self, R_world_segment: np.ndarray,
                sensed: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """The assumed ``R_world_segment`` (3, 3) of each open hinge parent.

        Args:
            R_world_segment: (n, 3, 3) targets; only rows where ``sensed`` are read.
            sensed: (n,) bool, segments with a measured orientation this frame.

        Returns:
            ``[(segment index, R_world_segment), ...]`` for every hinge whose parent segment
            is unsensed while its child and some ancestor are sensed.
        """
        out = []
        for h in self.hinges:
            if sensed[h.segment] or not sensed[h.child]:
                continue
            ancestor = next((a for a in h.ancestors if sensed[a]), None)
            if ancestor is None:
                continue
            k = hinge_angle(R_world_segment[ancestor], R_world_segment[h.child], h.axis, h.sign,
                            h.lower, h.upper)
            out.append((h.segment,
                        R_world_segment[h.child] @ axis_rotation(h.axis, h.sign * k).T))
        return out


def hinge_angle(R_world_parent: np.ndarray, R_world_child: np.ndarray, axis: str, sign: int,
                lower: float, upper: float) -> float:
    """The flexion [rad] in ``[lower, upper]`` turning the open segment least from the parent.

    Maximises ``trace(M R(a, -theta))`` with ``M = R_parent^T R_child``, ``a`` the unit axis
    and ``theta = sign * k``: by Rodrigues it is ``A cos(theta) + B sin(theta) + const`` with
    ``A = tr(M) - M_aa`` and ``B = -tr(M [a]x)`` (for ``a = e_i``: ``M_kj - M_jk`` on the cyclic
    pair ``(j, k)`` after ``i``).
    """
    M = R_world_parent.T @ R_world_child
    i = _AXES[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    A = float(np.trace(M) - M[i, i])
    B = float(M[k, j] - M[j, k])
    best = sign * float(np.arctan2(B, A))
    if lower <= best <= upper:
        return best
    score = [A * np.cos(sign * v) + B * np.sin(sign * v) for v in (lower, upper)]
    return lower if score[0] >= score[1] else upper


#: The limbs and the kinds of joint in them whose angles users read most (``jRightKnee``).
LIMB_JOINTS: dict[str, tuple[str, ...]] = {"legs": ("Hip", "Knee", "Ankle"),
                                           "arms": ("Shoulder", "Elbow", "Wrist")}
#: Segments above the pelvis whose orientation the trunk and head need.
TRUNK_SEGMENTS: tuple[str, ...] = ("L5", "L3", "T12", "T8", "Neck", "Head")


def segment_coverage(segments: Sequence[str], measured: Iterable[str]) -> dict[str, list[str]]:
    """``{"measured": [...], "assumed": [...]}``: which segments a sensor measures, in model order.

    Args:
        segments: Every segment of the model.
        measured: Segments with a calibrated sensor.
    """
    sensed = set(measured)
    return {"measured": [s for s in segments if s in sensed],
            "assumed": [s for s in segments if s not in sensed]}


def coverage_warning(joints: Mapping[str, object], measured: Iterable[str]) -> str | None:
    """A warning naming the key joint angles that are assumed (a side without a sensor), or None.

    A limb without any sensor is named as a whole ("the arms are assumed"); otherwise each kind
    of joint with an unsensed side is named with the segments that lack a sensor.

    Args:
        joints: ``HumanModel.ball_joints`` (name -> joint with ``spec``).
        measured: Segments with a calibrated sensor.
    """
    sensed = set(measured)
    parts = []
    for limb, kinds in LIMB_JOINTS.items():
        specs = {k: [joints[f"j{side}{k}"].spec for side in ("Right", "Left")  # type: ignore[attr-defined]
                     if f"j{side}{k}" in joints] for k in kinds}
        limb_segments = {s for group in specs.values() for spec in group
                         for s in (spec.parent, spec.child)} - {"Pelvis", "T8"}
        if not sensed & limb_segments:
            parts.append(f"the {limb} are assumed (no {limb[:-1]} sensors)")
            continue
        open_kinds, missing = [], []
        for kind, group in specs.items():
            unsensed = [s for spec in group for s in (spec.parent, spec.child) if s not in sensed]
            if unsensed:
                open_kinds.append(kind.lower())
                missing += [s for s in unsensed if s not in missing]
        if open_kinds:
            listed = " and ".join(open_kinds) if len(open_kinds) < 3 else (
                f"{', '.join(open_kinds[:-1])} and {open_kinds[-1]}")
            parts.append(f"{listed} angles are assumed, not measured (no sensor on "
                         f"{', '.join(missing)})")
    if "Pelvis" in sensed and not sensed & set(TRUNK_SEGMENTS):
        parts.append("the trunk and head are assumed upright over the pelvis (no sensor above it)")
    if not parts:
        return None
    return ("; ".join(parts) + ": unsensed segments follow a neutral posture (hinge knees and "
            "elbows, trunk over the pelvis, arms hanging); summary.json segments lists what is "
            "measured")
