"""Self-collision between capsules: distances and linearised keep-apart rows.

A capsule is the set of points within a radius of a segment fixed to a link. The distance of
two capsules is the distance of their segments minus both radii [m] (negative: they overlap).
For a step ``dq`` its first-order change is ``n^T (J_p - J_q) dq``, where ``p``, ``q`` are the
segments' closest points, ``n`` the unit vector from ``q`` to ``p`` and ``J_p`` the world linear
Jacobian of the point ``p`` moving with its link.
"""

from __future__ import annotations

from collections.abc import Sequence

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


def witness_segments(a0: np.ndarray, b0: np.ndarray, a1: np.ndarray,
                     b1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The five segment pairs (..., 5, 3) whose closest points are a capsule pair's witnesses.

    Both segments, and each end point (a segment of length 0) against the other segment:
    ``(first_a, first_b, second_a, second_b)``.
    """
    return (np.stack([a0, a0, b0, a0, a0], axis=-2), np.stack([b0, a0, b0, b0, b0], axis=-2),
            np.stack([a1, a1, a1, a1, b1], axis=-2), np.stack([b1, b1, b1, a1, b1], axis=-2))


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
        self._slots = [np.array([self._links.index(f) for f in side], dtype=int)
                       for side in self._frames]
        self._a = np.array([[x.a for x in first], [x.a for x in second]]).reshape(2, -1, 3)
        self._b = np.array([[x.b for x in first], [x.b for x in second]]).reshape(2, -1, 3)
        self._radius = np.array([x.radius for x in first]) + np.array([x.radius for x in second])
        self.margin = float(margin)
        self.activation = float(activation)
        self._cached_q: np.ndarray | None = None
        self._cached: tuple[np.ndarray, ...] = ()

    @property
    def links(self) -> list[int]:
        """Frame indices of the links carrying the capsules (the order :meth:`along` wants)."""
        return list(self._links)

    def _ends(self, R_links: np.ndarray, o_links: np.ndarray
              ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """World end points ``a``, ``b`` (..., k, 3) [m] of the first and second capsules.

        ``R_links`` (..., L, 3, 3) and ``o_links`` (..., L, 3) [m] are the world poses of
        :attr:`links`.
        """
        a, b = [], []
        for side in range(2):
            R, o = R_links[..., self._slots[side], :, :], o_links[..., self._slots[side], :]
            a.append(np.einsum("...kij,kj->...ki", R, self._a[side]) + o)
            b.append(np.einsum("...kij,kj->...ki", R, self._b[side]) + o)
        return a, b

    def along(self, R_links: np.ndarray, o_links: np.ndarray) -> np.ndarray:
        """Exact distance of each pair (N, k) [m] along a motion, all frames at once.

        Args:
            R_links: (N, L, 3, 3) world rotations of :attr:`links`.
            o_links: (N, L, 3) world origins of :attr:`links` [m].
        """
        if not self.pairs:
            return np.zeros((len(R_links), 0))
        a, b = self._ends(R_links, o_links)
        p, q = closest_points(*witness_segments(a[0], b[0], a[1], b[1]))
        return np.linalg.norm(p - q, axis=-1).min(axis=-1) - self._radius

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
        a, b = self._ends(configuration.rotations(self._links),
                          configuration.positions(self._links))
        # Pairs surely farther apart than ``activation`` keep a lower bound as their distance.
        mid = [(a[i] + b[i]) / 2 for i in range(2)]
        half = [np.linalg.norm(b[i] - a[i], axis=1) / 2 for i in range(2)]
        bound = np.linalg.norm(mid[0] - mid[1], axis=1) - half[0] - half[1] - self._radius
        p = np.repeat(mid[0], 5, axis=0)
        q = np.repeat(mid[1], 5, axis=0)
        d = np.repeat(bound, 5)
        near = np.flatnonzero(bound < self.activation)
        if len(near):
            ends = witness_segments(a[0][near], b[0][near], a[1][near], b[1][near])
            rows = (5 * near[:, None] + np.arange(5)).reshape(-1)
            p[rows], q[rows] = closest_points(*(x.reshape(-1, 3) for x in ends))
            d[rows] = np.linalg.norm(p[rows] - q[rows], axis=1) - np.repeat(self._radius[near], 5)
        self._cached_q, self._cached = configuration.q, (p, q, d)
        return p, q, d

    @property
    def last_min_distance(self) -> float:
        """The smallest distance (or lower bound) of the last configuration looked at [m]."""
        return float(self._cached[2].min()) if len(self._cached) and len(self._cached[2]) \
            else np.inf

    def distances(self, configuration: Configuration) -> np.ndarray:
        """Distance of each pair (k,) [m] (negative when they overlap).

        Exact below ``activation``; above it a lower bound (exact everywhere with an infinite
        ``activation``).
        """
        if not self.pairs:
            return np.zeros(0)
        return self._witnesses(configuration)[2].reshape(-1, 5).min(axis=1)

    def inequality(self, configuration: Configuration) -> Inequality:
        """Rows ``-n^T (J_p - J_q) dq <= d - margin`` for witnesses closer than ``activation``."""
        nv = configuration.model.nv
        if not self.pairs:
            return Inequality(np.zeros((0, nv)), np.zeros(0))
        p, q, d = self._witnesses(configuration)
        near = np.flatnonzero(d < self.activation)
        if not len(near):
            return Inequality(np.zeros((0, nv)), np.zeros(0))
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
