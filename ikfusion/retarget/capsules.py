"""Self-collision between capsules: distances and linearised keep-apart rows.

A capsule is the set of points within a radius of a segment fixed to a link. The distance of
two capsules is the distance of their segments minus both radii [m] (negative: they overlap).
For a step ``dq`` its first-order change is ``n^T (J_p - J_q) dq``, where ``p``, ``q`` are the
segments' closest points, ``n`` the unit vector from ``q`` to ``p`` and ``J_p`` the world linear
Jacobian of the point ``p`` moving with its link.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from ..ik.configuration import Configuration
from ..ik.limits.base import Inequality
from ..rotations import skew
from .robot_config import Capsule


def closest_points(a1: np.ndarray, b1: np.ndarray, a2: np.ndarray,
                   b2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of segments ``a1``-``b1`` and ``a2``-``b2``, batched over (..., 3).

    Returns:
        ``(p, q)``: the points on the first and on the second segment (..., 3) [m].
    """
    d1, d2, r = b1 - a1, b2 - a2, a1 - a2
    a = np.maximum(np.einsum("...i,...i->...", d1, d1), 1e-12)
    e = np.maximum(np.einsum("...i,...i->...", d2, d2), 1e-12)
    b = np.einsum("...i,...i->...", d1, d2)
    c = np.einsum("...i,...i->...", d1, r)
    f = np.einsum("...i,...i->...", d2, r)
    denom = a * e - b * b
    parallel = denom < 1e-12 * a * e
    s = np.where(parallel, 0.0, np.clip((b * f - c * e) / np.where(parallel, 1.0, denom), 0, 1))
    t = (b * s + f) / e
    below, above = t < 0.0, t > 1.0
    s = np.where(below, np.clip(-c / a, 0, 1), np.where(above, np.clip((b - c) / a, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    return a1 + s[..., None] * d1, a2 + t[..., None] * d2


def closest_points_sx(a1: ca.SX, b1: ca.SX, a2: ca.SX, b2: ca.SX) -> tuple[ca.SX, ca.SX]:
    """:func:`closest_points` of one segment pair (each end (3,) [m]) as a CasADi graph.

    The same formula and branches, for the compiled retargeting step.
    """
    d1, d2, r = b1 - a1, b2 - a2, a1 - a2
    a = ca.fmax(ca.dot(d1, d1), 1e-12)
    e = ca.fmax(ca.dot(d2, d2), 1e-12)
    b, c, f = ca.dot(d1, d2), ca.dot(d1, r), ca.dot(d2, r)
    denom = a * e - b * b
    parallel = denom < 1e-12 * a * e
    s = ca.if_else(parallel, 0.0,
                   ca.fmin(ca.fmax((b * f - c * e) / ca.if_else(parallel, 1.0, denom), 0.0), 1.0))
    t = (b * s + f) / e
    s = ca.if_else(t < 0.0, ca.fmin(ca.fmax(-c / a, 0.0), 1.0),
                   ca.if_else(t > 1.0, ca.fmin(ca.fmax((b - c) / a, 0.0), 1.0), s))
    t = ca.fmin(ca.fmax(t, 0.0), 1.0)
    return a1 + s * d1, a2 + t * d2


#: End point indices (0: ``a``, 1: ``b``) of the five witness segment pairs: both segments,
#: each end of the first against the second segment, each end of the second against the first.
#: ``(first_a, first_b, second_a, second_b)``.
WITNESS_ENDS = ([0, 0, 1, 0, 0], [1, 0, 1, 1, 1], [0, 0, 0, 0, 1], [1, 1, 1, 0, 1])


def witness_segments(first: np.ndarray, second: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The five segment pairs whose closest points are a capsule pair's witnesses.

    Args:
        first: End points ``a``, ``b`` (..., 2, 3) of the first capsules' segments [m].
        second: The same of the second capsules.

    Returns:
        ``(first_a, first_b, second_a, second_b)``, each (..., 5, 3) [m]: both segments, and
        each end point (a segment of length 0) against the other segment.
    """
    first_a, first_b, second_a, second_b = WITNESS_ENDS
    return (first[..., first_a, :], first[..., first_b, :],
            second[..., second_a, :], second[..., second_b, :])


class CapsulePairs:
    """Capsule pairs that must keep at least ``margin`` apart.

    Args:
        capsules: Name -> capsule.
        pairs: Name pairs to check.
        frame_ids: Link name -> Pinocchio frame index.
        margin: Smallest distance the constraint rows keep [m].
        activation: Pairs farther apart than this get no row [m].
    """

    def __init__(self, capsules: dict[str, Capsule], pairs: Sequence[tuple[str, str]],
                 frame_ids: dict[str, int], margin: float = 0.01,
                 activation: float = 0.06) -> None:
        self.pairs = list(pairs)
        first = [capsules[a] for a, _ in pairs]
        second = [capsules[b] for _, b in pairs]
        self._frames = [[frame_ids[x.link] for x in first], [frame_ids[x.link] for x in second]]
        self._links = sorted(set(self._frames[0]) | set(self._frames[1]))
        # First capsules then second ones: link slot, end points a, b in the link frame [m].
        self._slot = np.array([self._links.index(f) for f in self._frames[0] + self._frames[1]],
                              dtype=int)
        self._ab = np.array([[x.a, x.b] for x in first + second], dtype=float).reshape(-1, 2, 3)
        self._radius = np.array([x.radius for x in first]) + np.array([x.radius for x in second])
        half = np.linalg.norm(self._ab[:, 1] - self._ab[:, 0], axis=1) / 2
        k = len(self.pairs)
        self._reach = half[:k] + half[k:] + self._radius  # centre distance that may touch [m]
        self.margin = float(margin)
        self.activation = float(activation)
        self._cached_q: np.ndarray | None = None
        self._cached: tuple[np.ndarray, ...] = ()

    @property
    def frame_pairs(self) -> list[tuple[int, int]]:
        """Frame indices of each pair's first and second capsule's link."""
        return list(zip(self._frames[0], self._frames[1]))

    def geometry(self) -> np.ndarray:
        """The capsules as the compiled step's input (12k + k) [m].

        End points in their link frames, first capsules then second ones, each ``a`` then
        ``b``; then each pair's summed radius.
        """
        return np.concatenate([self._ab.reshape(-1), self._radius])

    @property
    def links(self) -> list[int]:
        """Frame indices of the links carrying the capsules (the order :meth:`along` wants)."""
        return list(self._links)

    def _ends(self, R_links: np.ndarray, o_links: np.ndarray) -> np.ndarray:
        """World end points (..., 2k, 2, 3) [m] of the first capsules, then the second ones.

        ``R_links`` (..., L, 3, 3) and ``o_links`` (..., L, 3) [m] are the world poses of
        :attr:`links`.
        """
        return (np.einsum("...kij,kej->...kei", R_links[..., self._slot, :, :], self._ab)
                + o_links[..., self._slot, None, :])

    def along(self, R_links: np.ndarray, o_links: np.ndarray) -> np.ndarray:
        """Exact distance of each pair (N, k) [m] along a motion, all frames at once.

        Args:
            R_links: (N, L, 3, 3) world rotations of :attr:`links`.
            o_links: (N, L, 3) world origins of :attr:`links` [m].
        """
        k = len(self.pairs)
        if not k:
            return np.zeros((len(R_links), 0))
        ends = self._ends(R_links, o_links)
        p, q = closest_points(*witness_segments(ends[:, :k], ends[:, k:]))
        return np.linalg.norm(p - q, axis=-1).min(axis=-1) - self._radius

    def min_distance(self, R_links: np.ndarray, o_links: np.ndarray) -> float | None:
        """The smallest distance of any pair along a motion [m], None without pairs.

        The value of ``along(R_links, o_links).min()``, computed exactly only where a pair
        may come that close: a pair's centre distance minus its reach bounds its distance from
        below, so the (frame, pair) of the lowest bound gives an exact distance that any
        closer one must undercut through its bound.

        Args:
            R_links: (N, L, 3, 3) world rotations of :attr:`links`.
            o_links: (N, L, 3) world origins of :attr:`links` [m].
        """
        k = len(self.pairs)
        if not k or not len(R_links):
            return None
        centres = ((R_links[:, self._slot] @ self._ab.mean(axis=1)[:, :, None])[..., 0]
                   + o_links[:, self._slot])  # (N, 2k, 3)
        bound = np.linalg.norm(centres[:, :k] - centres[:, k:], axis=-1) - self._reach
        first = np.unravel_index(np.argmin(bound), bound.shape)
        closest = float(self._entry_distances(R_links, o_links, *(np.array([i]) for i in first))
                        .min())
        # a micrometre of slack: the bound's own round-off must not drop an entry
        frames, pairs = np.nonzero(bound <= closest + 1e-6)
        return float(self._entry_distances(R_links, o_links, frames, pairs).min())

    def _entry_distances(self, R_links: np.ndarray, o_links: np.ndarray, frames: np.ndarray,
                         pairs: np.ndarray) -> np.ndarray:
        """Exact distances (m,) [m] of the pairs ``pairs`` (m,) in the frames ``frames`` (m,)."""
        ends = []
        for capsule in (pairs, len(self.pairs) + pairs):  # first capsules, second ones
            slot = self._slot[capsule]
            ends.append(np.einsum("mij,mej->mei", R_links[frames, slot], self._ab[capsule])
                        + o_links[frames, slot][:, None])
        p, q = closest_points(*witness_segments(*ends))
        return np.linalg.norm(p - q, axis=-1).min(axis=-1) - self._radius[pairs]

    def _witnesses(self, configuration: Configuration) -> tuple[np.ndarray, ...]:
        """Closest points of each pair's segments and of each end point to the other segment.

        Returns:
            ``(p, q, d)``: points on the first and second capsule (5k, 3) [m] and the
            distances they give (5k,) [m], five candidates per pair, pair-major. The pair's
            distance is the smallest; constraining all five keeps the linearisation smooth
            where the closest points jump (segments nearly parallel).
        """
        if self._cached_q is configuration.q:  # the same configuration as last time
            return self._cached
        k = len(self.pairs)
        ends = self._ends(configuration.rotations(self._links),
                          configuration.positions(self._links))
        # Pairs surely farther apart than ``activation`` keep a lower bound as their distance.
        mid = 0.5 * ends.sum(axis=1)
        bound = np.linalg.norm(mid[:k] - mid[k:], axis=1) - self._reach
        p = np.repeat(mid[:k], 5, axis=0)
        q = np.repeat(mid[k:], 5, axis=0)
        d = np.repeat(bound, 5)
        near = np.flatnonzero(bound < self.activation)
        if len(near):
            rows = (5 * near[:, None] + np.arange(5)).reshape(-1)
            p_near, q_near = closest_points(*(x.reshape(-1, 3) for x in witness_segments(
                ends[near], ends[k + near])))
            p[rows], q[rows] = p_near, q_near
            d[rows] = np.linalg.norm(p_near - q_near, axis=1) - np.repeat(self._radius[near], 5)
        self._cached_q, self._cached = configuration.q, (p, q, d)
        return p, q, d

    def _distances(self, configuration: Configuration) -> np.ndarray:
        """Witness distances (5k,) [m] of ``configuration``.

        A configuration with a ``capsule_distances()`` method (the compiled retargeting step)
        gives them exactly; otherwise :meth:`_witnesses` does.
        """
        compiled = getattr(configuration, "capsule_distances", None)
        distances = compiled() if compiled is not None else None
        self._last_distances = self._witnesses(configuration)[2] if distances is None \
            else distances
        return self._last_distances

    @property
    def last_min_distance(self) -> float:
        """The smallest distance (or lower bound) of the last configuration looked at [m]."""
        d = getattr(self, "_last_distances", np.zeros(0))
        return float(d.min()) if len(d) else np.inf

    def distances(self, configuration: Configuration) -> np.ndarray:
        """Distance of each pair (k,) [m] (negative when they overlap).

        Exact below ``activation``; above it a lower bound (exact everywhere with an infinite
        ``activation``).
        """
        if not self.pairs:
            return np.zeros(0)
        return self._distances(configuration).reshape(-1, 5).min(axis=1)

    def inequality(self, configuration: Configuration) -> Inequality:
        """Rows ``-n^T (J_p - J_q) dq <= d - margin`` for witnesses closer than ``activation``."""
        nv = configuration.model.nv
        if not self.pairs:
            return Inequality(np.zeros((0, nv)), np.zeros(0))
        d = self._distances(configuration)
        near = np.flatnonzero(d < self.activation)
        if not len(near):
            return Inequality(np.zeros((0, nv)), np.zeros(0))
        compiled = getattr(configuration, "capsule_rows", None)  # (5k, nv) when it has them
        rows = compiled(np.unique(near // 5)) if compiled is not None else None
        if rows is not None:
            return Inequality(rows[near], d[near] - self.margin)
        p, q, _ = self._witnesses(configuration)
        gap = p[near] - q[near]
        n = gap / np.maximum(np.linalg.norm(gap, axis=1), 1e-9)[:, None]
        Jp = self._point_jacobians(configuration, [self._frames[0][k // 5] for k in near],
                                   p[near])
        Jq = self._point_jacobians(configuration, [self._frames[1][k // 5] for k in near],
                                   q[near])
        return Inequality(-np.einsum("mi,min->mn", n, Jp - Jq), d[near] - self.margin)

    @staticmethod
    def _point_jacobians(configuration: Configuration, frame_ids: list[int],
                         points: np.ndarray) -> np.ndarray:
        """World linear Jacobians (m, 3, nv) of world ``points`` (m, 3) [m] moving with frames."""
        J = np.array([configuration.jacobian(f) for f in frame_ids])
        r = points - configuration.positions(frame_ids)
        return J[:, :3] - skew(r) @ J[:, 3:]
