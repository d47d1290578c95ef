"""Velocity bounds: how far the configuration may move from the previous frame in one frame."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..configuration import Configuration


class VelocityLimit:
    """Box ``-v_max dt <= (q ⊕ dq) ⊖ q_prev <= v_max dt`` on every tangent coordinate.

    Args:
        max_velocity: Per tangent coordinate (nv,) [m/s for the root translation, rad/s else].
    """

    def __init__(self, max_velocity: npt.ArrayLike) -> None:
        self.max_velocity = np.asarray(max_velocity, dtype=float).reshape(-1)
        self.q_previous: np.ndarray | None = None
        self.dt = 0.0
        # dt, max_velocity * dt and its negative
        self._span = (0.0, np.zeros_like(self.max_velocity), np.zeros_like(self.max_velocity))
        self._zero = np.zeros(())  # (an array: no conversion of a Python 0.0 per call)
        # the bounds (lb, ub): the rows of one array, written in place by each call (the tree
        # step's kernel reads them there, :meth:`.tree_solve.TreeClosedForm.step`)
        both = self._both = np.zeros((2, len(self.max_velocity)))
        self._bounds = (both[0], both[1])

    def set_previous(self, q_previous: npt.ArrayLike | None, dt: float) -> None:
        """The previous frame's configuration and the time step [s] (None: no bound)."""
        self.q_previous = None if q_previous is None else np.asarray(q_previous, dtype=float)
        self.dt = float(dt)

    def span(self) -> np.ndarray | None:
        """``v_max dt`` (nv,) of the current time step; None when there is no bound.

        The same array at every call, written again when the time step changes (the
        timestamps' round-off changes it in about half the frames of a steady rate).
        """
        if self.q_previous is None or self.dt <= 0.0:
            return None
        dt, span, negative = self._span
        if dt != self.dt:  # a new time step: v_max dt and its negative in place
            np.multiply(self.max_velocity, self.dt, out=span)
            np.negative(span, out=negative)
            self._span = (self.dt, span, negative)
        return span

    def bounds(self, configuration: Configuration,
               moved: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """``(lb, ub)`` on ``dq``, or None when there is no previous frame.

        ``moved`` is ``q ⊖ q_previous`` when the caller has it already. The same two arrays
        at every call (:attr:`bound_rows`), overwritten by the next.
        """
        span, previous = self.span(), self.q_previous
        if span is None or previous is None:
            return None
        if moved is None:
            moved = configuration.difference(previous)
        negative = self._span[2]
        bounds = self._bounds
        lb, ub = bounds
        np.subtract(negative, moved, out=lb)  # then clipped in place
        np.subtract(span, moved, out=ub)
        np.minimum(lb, self._zero, out=lb)
        np.maximum(ub, self._zero, out=ub)
        return bounds

    @property
    def bound_rows(self) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """Where :meth:`bounds` writes: one array (2, nv) and its rows ``(lb, ub)`` it returns.

        For a native writer of the same numbers (:mod:`..step_rows`).
        """
        return self._both, self._bounds
