"""Solver outputs: one :class:`Pose` per frame, a :class:`Motion` for a recording."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..model.human_model import HumanModel


@dataclass
class Pose:
    """The solved body at one frame.

    Attributes:
        time: [s].
        q: Configuration (nq,).
        contacts: Contact point name -> in contact.
        solve_time: Wall time of the solve [s].
        iterations: Gauss-Newton steps taken.
        relaxed: True when constraints had to be relaxed this frame.
        residual_source: Computes :attr:`residuals` when first asked for (so a solve that does
            not look at them does not pay for them).
    """

    model: HumanModel
    time: float
    q: np.ndarray
    contacts: dict[str, bool]
    solve_time: float
    iterations: int
    relaxed: bool = False
    residual_source: Callable[[], dict[str, dict[str, float]]] | None = field(default=None,
                                                                              repr=False)
    _residuals: dict[str, dict[str, float]] | None = field(default=None, init=False, repr=False)

    @property
    def residuals(self) -> dict[str, dict[str, float]]:
        """Task name -> residual summary.

        Orientation errors [deg] per tracked segment, position errors [m] per targeted site,
        slide [m] of each planted contact point from its anchor.
        """
        if self._residuals is None:
            self._residuals = self.residual_source() if self.residual_source else {}
        return self._residuals

    def segment_rotation(self, name: str) -> np.ndarray:
        """``R_world_segment``."""
        return self.model.segment_rotation(self.q, name)

    def segment_position(self, name: str) -> np.ndarray:
        """``p_world_segment`` [m] (segment origin)."""
        return self.model.segment_position(self.q, name)

    def site_position(self, name: str) -> np.ndarray:
        """``p_world_site`` [m]."""
        return self.model.site_position(self.q, name)

    @property
    def joint_angles(self) -> dict[str, float]:
        """Anatomical joint angles [deg], keys like ``jRightKnee_flex``."""
        return self.model.joint_angles(self.q)


@dataclass
class Motion:
    """A solved recording.

    Attributes:
        time: (N,) [s].
        q: (N, nq) configurations.
        contact_names: Names of the contact points (columns of ``contacts``).
        contacts: (N, k) bool.
        solve_time: (N,) [s].
        iterations: (N,) Gauss-Newton steps.
        relaxed: (N,) frames whose constraints were relaxed.
        warnings: Messages for the user (also written to ``summary.json``).
    """

    model: HumanModel
    time: np.ndarray
    q: np.ndarray
    contact_names: list[str]
    contacts: np.ndarray
    solve_time: np.ndarray
    iterations: np.ndarray
    relaxed: np.ndarray
    warnings: list[str] = field(default_factory=list)

    @classmethod
    def from_poses(cls, model: HumanModel, poses: Sequence[Pose], contact_names: Sequence[str],
                   warnings: Sequence[str] = ()) -> Motion:
        """Stack per-frame poses."""
        return cls(
            model=model,
            time=np.array([p.time for p in poses]),
            q=np.array([p.q for p in poses]).reshape(len(poses), model.model.nq),
            contact_names=list(contact_names),
            contacts=_contact_rows(poses, contact_names),
            solve_time=np.array([p.solve_time for p in poses]),
            iterations=np.array([p.iterations for p in poses], dtype=int),
            relaxed=np.array([p.relaxed for p in poses], dtype=bool),
            warnings=list(warnings),
        )

    def __len__(self) -> int:
        return len(self.time)

    @property
    def rate(self) -> float:
        """Mean frame rate [Hz]."""
        return float((len(self.time) - 1) / (self.time[-1] - self.time[0])) if len(
            self.time) > 1 else 0.0

    def joint_angles(self) -> np.ndarray:
        """(N, 3 * joints) [deg] in the order of ``model.angle_columns``."""
        return self.model.joint_angle_matrix(self.q)


def _contact_rows(poses: Sequence[Pose], names: Sequence[str]) -> np.ndarray:
    """(N, k) bool: ``pose.contacts.get(name, False)`` of each pose and name.

    A recording takes few patterns of contacts: each is converted once and gathered.
    """
    absent = [False] * len(names)
    patterns: dict[tuple[object, ...], int] = {}
    index = np.fromiter((patterns.setdefault(tuple(map(p.contacts.get, names, absent)),
                                             len(patterns)) for p in poses),
                        dtype=np.intp, count=len(poses))
    table = np.array(list(patterns), dtype=bool).reshape(len(patterns), len(names))
    return table[index]
