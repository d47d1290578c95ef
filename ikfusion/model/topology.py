"""What the body's tree says about its parts: feet, their contact points, legs and toe joints.

Read from the model's joint tree (each ball joint links a parent segment to a child) and from
the segment carrying each site (:attr:`SiteInfo.segment`), never from names:

* a *foot* is the segment nearest the root, on a contact point's chain, that carries a contact
  point (the heel's segment; the toe point's segment hangs below it);
* a contact point *on its foot* (a heel) sits on the foot itself; the others (toes) sit on a
  segment below it;
* a foot's *leg* is its chain up to the root, the root excluded;
* a *toe joint* links a foot to a segment below it that carries a contact point.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .human_model import HumanModel


@dataclass(frozen=True)
class FootLayout:
    """Which contact points share a foot, and which stand on the foot itself.

    Attributes:
        same_foot: (k, k) point i and point j are on one foot.
        on_foot: (k,) points on the foot segment itself (heels).
        below_foot: (k,) points on a segment below the foot (toes).
        feet: (f, k) one row per foot, in the order of its first point: its points.
    """

    same_foot: np.ndarray
    on_foot: np.ndarray
    below_foot: np.ndarray
    feet: np.ndarray


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
        for a in (same, on_foot, below, feet):
            a.setflags(write=False)
        return FootLayout(same, on_foot, below, feet)

    def is_toe_joint(self, parent: str, child: str) -> bool:
        """Does the joint ``parent`` -> ``child`` link a foot to a segment with contact points?"""
        carriers = {self.site_segment[p] for p in self.contact_points}
        return child in carriers and self.foot_of_segment(child) == parent

    def foot_of_segment(self, segment: str) -> str | None:
        """The foot ``segment`` belongs to (itself, or the foot it hangs from); None if none."""
        carriers = {self.site_segment[p] for p in self.contact_points}
        feet = [s for s in self.chain(segment) if s in carriers]
        return feet[-1] if feet else None
