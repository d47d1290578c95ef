"""Drift correction: bringing an inertial body to absolute tag positions (from UWB).

Inertial tracking chains contacts and drifts a little each step; UWB tags say where the head and
feet are. The correction compares, after each frame, the solved tag sites with the measured
positions (horizontal error, weighted by the measurements' covariances) and acts on the feet:

* ``slide``: every planted point is moved toward the correction at once (a first-order lag of
  ``time_constant``); the body follows at once, planted feet slide.
* ``no-slide``: planted points never move; each point that touches down is planted offset by the
  correction (at most ``max_step`` per touch-down), so the body walks into place step by step.
* ``off``: tags are only reported.

The first fix places the body in the tag frame at once (there is nothing to slide yet); the
frames solved before it are moved by the same offset afterwards (:meth:`DriftCorrection.
place_start`), so the whole motion is in the tag frame. Heights come from the floor, so only
the horizontal error is corrected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .ik.pose import Motion, Pose
from .ik.solver import Solver

#: Correction modes.
MODES = ("off", "slide", "no-slide")


@dataclass
class SiteFixes:
    """Measured positions of model sites on the frame times.

    Attributes:
        site: Model site carrying the tag (``HeadTop``, ``LeftFootTop``, ``RightFootTop``).
        p_world: (N, 3) positions [m], NaN where there is no fix.
        cov: (N, 3, 3) their covariances [m^2].
    """

    site: str
    p_world: np.ndarray
    cov: np.ndarray


@dataclass
class DriftCorrection:
    """Per-frame correction of a solve by tag positions (see the module docstring).

    Attributes:
        fixes: The measured sites.
        mode: ``off``, ``slide`` or ``no-slide``.
        time_constant: Lag of the ``slide`` correction [s].
        max_step: Largest offset of one touch-down in ``no-slide`` [m].
        gap: (N,) remaining horizontal gap after each frame [m] (NaN without a fix).
    """

    fixes: list[SiteFixes]
    mode: str = "no-slide"
    time_constant: float = 0.5
    max_step: float = 0.05
    gap: np.ndarray = field(default_factory=lambda: np.zeros(0))
    _placed: bool = False
    _placement: tuple[int, np.ndarray] | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"correction mode must be one of {', '.join(MODES)}, not "
                             f"{self.mode!r}")
        n = len(self.fixes[0].p_world) if self.fixes else 0
        self.gap = np.full(n, np.nan)

    def horizontal_error(self, pose: Pose, k: int) -> np.ndarray | None:
        """Information-weighted mean of (measured - solved) over the sites with a fix [m]."""
        info_sum, weighted = np.zeros((2, 2)), np.zeros(2)
        for f in self.fixes:
            p, C = f.p_world[k], f.cov[k]
            if not (np.isfinite(p).all() and np.isfinite(C).all()):
                continue
            info = np.linalg.inv(C[:2, :2] + 1e-9 * np.eye(2))
            info_sum += info
            weighted += info @ (p[:2] - pose.site_position(f.site)[:2])
        if not info_sum.any():
            return None
        return np.asarray(np.linalg.solve(info_sum, weighted))

    def after_frame(self, solver: Solver, pose: Pose, k: int, dt: float) -> None:
        """Compare frame ``k`` with the fixes and steer the solver's feet for the next frames."""
        error = self.horizontal_error(pose, k)
        if error is None:
            return
        self.gap[k] = float(np.linalg.norm(error))
        delta = np.array([error[0], error[1], 0.0])
        if self.mode == "off":
            return
        if not self._placed:
            solver.translate(delta)
            self._placed = True
            self._placement = (k, delta)
        elif self.mode == "slide":
            solver.shift_anchors(delta * min(1.0, dt / self.time_constant))
        else:
            norm = float(np.linalg.norm(delta))
            scale = min(1.0, self.max_step / norm) if norm > 0 else 0.0
            solver.set_touchdown_offset(delta * scale)

    def place_start(self, motion: Motion) -> None:
        """Move the frames solved before the first fix by its offset (in place).

        Until a tag is first heard the body stands in the inertial frame; the first fix moves
        it into the tag frame (:meth:`after_frame`), and this moves the frames before, and the
        fix's own frame, along, so the motion does not start with a jump.
        """
        if self._placement is None:
            return
        k, delta = self._placement
        motion.q[:k + 1, :2] += delta[:2]
        self.gap[:k + 1] = np.nan  # measured before the placement
