"""What the body's tree says about its parts: feet, their contact points, legs and toe joints.

Read from the model's joint tree (each ball joint links a parent segment to a child) and from
the segment carrying each site (:attr:`SiteInfo.segment`), never from names. A *carrier* is a
segment that carries a contact point:

* the *foot* of a contact point (the group of points that move as one body part) is the carrier
  itself; a carrier with no carrier below it whose parent is a carrier (the toes) belongs to its
  parent's foot. The feet proper (heel and toes) are then one group each, and a knee (on the
  lower leg), a palm (on the hand), the chest and shoulder blades (on the upper trunk) or the
  sacrum and buttocks (on the pelvis, the root) are groups of their own; a segment that carries
  no point is on no foot;
* a contact point *on its foot* (a heel, a knee, a palm) sits on the group's segment itself; the
  others (toes) sit on a segment below it; a group with both *steps* (a foot proper: heel-toe
  roll, IMU stance and swing leading apply to it);
* a group's *limb* is its chain up to the first segment that branches (the root, the chest);
* a *toe joint* links a foot to a segment below it that carries a contact point.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .human_model import HumanModel


def segment_parents(model: HumanModel) -> dict[str, str | None]:
    """Segment -> its parent segment in the model's tree (None for the root)."""
    parents: dict[str, str | None] = {s: None for s in model.segment_names}
    for joint in model.ball_joints.values():
        parents[joint.spec.child] = joint.spec.parent
    return parents


@dataclass(frozen=True)
class FootLayout:
    """Which contact points share a foot, and which stand on the foot itself.

    Attributes:
        same_foot: (k, k) point i and point j are on one foot.
        on_foot: (k,) points on the foot segment itself (heels).
        below_foot: (k,) points on a segment below the foot (toes).
        feet: (f, k) one row per foot, in the order of its first point: its points.
        stepping: (k,) points of a foot proper (one with points on and below it: heel, toe),
            not a knee or a palm.
        same_segment: (k, k) point i and point j are on one rigid segment (the shoulder
            blades and chest on T8; the sacrum and buttocks on the pelvis; a heel and its toe
            are not).
    """

    same_foot: np.ndarray
    on_foot: np.ndarray
    below_foot: np.ndarray
    feet: np.ndarray
    stepping: np.ndarray
    same_segment: np.ndarray

    @cached_property
    def other_foot(self) -> np.ndarray:
        """(k, k) point i and point j are not on one foot (``~same_foot``, worked out once)."""
        other = ~np.asarray(self.same_foot, dtype=bool)
        other.setflags(write=False)
        return other

    @cached_property
    def memos(self) -> dict[str, Any]:
        """Answers of the contact rules' mask functions, per pattern (:mod:`.ik.point_masks`)."""
        return {}

    @cached_property
    def shares_segment(self) -> np.ndarray:
        """(k,) points sharing their rigid segment with another point (worked out once)."""
        shares = np.count_nonzero(np.asarray(self.same_segment, dtype=bool), axis=1) > 1
        shares.setflags(write=False)
        return shares


@dataclass(frozen=True)
class BodyTopology:
    """The segment tree and the sites on it (see the module docstring).

    Attributes:
        segments: Segment names; the first is the root.
        parent: Child segment -> parent segment (the root has none).
        site_segment: Site name -> segment carrying it.
        contact_points: Names of the contact sites.
    """

    segments: tuple[str, ...]
    parent: dict[str, str]
    site_segment: dict[str, str]
    contact_points: tuple[str, ...]

    @classmethod
    def of(cls, model: HumanModel) -> BodyTopology:
        """The topology of ``model`` (its ball joints and sites)."""
        parent = {j.spec.child: j.spec.parent for j in model.ball_joints.values()}
        sites = {n: info.segment for n, info in model.sites.items()}
        return cls(tuple(model.segment_names), parent, sites,
                   tuple(model.sites_of_kind("contact")))

    def chain(self, segment: str) -> list[str]:
        """``segment`` and its ancestors up to the root, the root excluded."""
        out = []
        while segment in self.parent:
            out.append(segment)
            segment = self.parent[segment]
        return out

    def foot_of(self, site: str) -> str | None:
        """The foot segment carrying ``site`` or the segment it hangs from (None: not on a foot)."""
        return self.foot_of_segment(self.site_segment[site])

    def feet(self, points: Sequence[str]) -> list[str]:
        """The feet of ``points`` (contact points), each once, in the order of the points."""
        out: list[str] = []
        for p in points:
            foot = self.foot_of(p)
            if foot is not None and foot not in out:
                out.append(foot)
        return out

    def foot_layout(self, points: Sequence[str]) -> FootLayout:
        """The :class:`FootLayout` of the contact points ``points``."""
        foot = [self.foot_of(p) or p for p in points]
        k = len(foot)
        same = np.array([[a == b for b in foot] for a in foot], dtype=bool).reshape(k, k)
        on_foot = np.array([self.site_segment[p] == f for p, f in zip(points, foot)], dtype=bool)
        names = self.feet(points)
        feet = np.array([[g == f for g in foot] for f in names], dtype=bool).reshape(len(names), k)
        below = ~on_foot
        stepping = (same & on_foot[None, :]).any(axis=1) & (same & below[None, :]).any(axis=1)
        carrier = [self.site_segment[p] for p in points]
        rigid = np.array([[a == b for b in carrier] for a in carrier], dtype=bool).reshape(k, k)
        for a in (same, on_foot, below, feet, stepping, rigid):
            a.setflags(write=False)
        return FootLayout(same, on_foot, below, feet, stepping, rigid)

    def is_toe_joint(self, parent: str, child: str) -> bool:
        """Does the joint ``parent`` -> ``child`` link a foot to a segment with contact points?"""
        return child in self._carriers() and self.foot_of_segment(child) == parent

    def foot_of_segment(self, segment: str) -> str | None:
        """The foot ``segment`` belongs to; None unless it carries a contact point.

        A carrier is its own foot (the root too: a pelvis resting on the floor), except a
        carrier with no carrier below it whose parent carries points (toes): its parent's.
        A segment without points (the head under a chest that rests face down) is on no foot.
        """
        carriers = self._carriers()
        if segment not in carriers:
            return None
        parent = self.parent.get(segment)
        below = any(segment in self.chain(c)[1:] for c in carriers)
        return parent if parent in carriers and not below else segment

    def limb(self, segment: str) -> list[str]:
        """``segment`` and its ancestors up to the first one with several children, excluded.

        A foot's leg ends at the hip (below the root), a hand's arm at the shoulder (below the
        chest): what eases back to its sensors when the point lets go.
        """
        children: dict[str, int] = {}
        for p in self.parent.values():
            children[p] = children.get(p, 0) + 1
        out = []
        for s in self.chain(segment):
            out.append(s)
            if children.get(self.parent.get(s, ""), 0) > 1:
                break
        return out

    def _carriers(self) -> set[str]:
        return {self.site_segment[p] for p in self.contact_points}
