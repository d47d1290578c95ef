"""The ranges of motion linearised by the compiled step function (:mod:`.compiled_ranges`).

The step function's outputs ``G_ranges``, ``room_up`` and ``room_down`` are
:meth:`.limits.JointRangeLimit.linearise` to rounding (about 1e-11 in a rate, 1e-14 rad in a
room) in about a tenth of the time of the NumPy twin. :func:`evaluated_ranges` reads them
from a step of the Gauss-Newton loop; :class:`StepRangeRows` evaluates the step function for
the ranges alone (the projection's fallback QP, :mod:`.projection`).
"""

from __future__ import annotations

import numpy as np

from .bound_function import BoundFunction
from .compiled import CompiledKinematics
from .compiled_inputs import read_only
from .configuration import Configuration
from .fast_math import count_true
from .limits import JointRangeLimit
from .limits.base import Inequality
from .limits.joint_range import LinearisedRanges

#: The step function's outputs: G_ranges, room_up, room_down (:mod:`.compiled`), the last two
#: one after the other.
_G, _UP, _DOWN = 7, 8, 9


class RateRows:
    """Where the rates of each angle lie among ``G_ranges``' structural nonzeros.

    Finds the angles whose rates are all 0 (at gimbal lock) from three nonzeros a row instead
    of a search of every row of ``G``; most steps have none, known from one nonzero rate a
    row (the witnesses, kept from the last search): when each of those is nonzero, no row is
    all zeros (the same mask, all False, for a fraction of the work).

    Args:
        rows: (angles, 3) indices into the nonzeros (:func:`.frame_problem.rate_rows`).
    """

    def __init__(self, rows: np.ndarray) -> None:
        self.rows = rows
        self._witnesses = rows[:, 0]
        self._none = np.zeros(len(rows), dtype=bool)
        self._none.setflags(write=False)
        self._count = len(rows)
        self._all = np.arange(len(rows))
        # the ranges read from the last step function (the same arrays at every evaluation)
        self._read: tuple[BoundFunction | None, LinearisedRanges | None] = (None, None)

    def still(self, nonzeros: np.ndarray) -> np.ndarray:
        """Mask (angles,) of the rows whose rates are all 0, from ``G_ranges``' nonzeros."""
        if count_true(nonzeros.take(self._witnesses)) == self._count:
            return self._none
        rates = nonzeros.take(self.rows)
        # (logical_or.reduce: ndarray.any without its Python-level dispatch)
        moving = np.logical_or.reduce(rates, axis=1)
        self._witnesses = self.rows[self._all, np.argmax(rates != 0.0, axis=1)]
        return np.logical_not(moving)

    def ranges(self, step: BoundFunction) -> LinearisedRanges:
        """``G`` and the rooms of the evaluated ``step`` (arrays read in place)."""
        read_from, ranges = self._read
        if read_from is not step or ranges is None:
            ranges = LinearisedRanges(step.output(_G), step.vectors(_UP, 2))
            self._read = (step, ranges)
            return ranges
        step.output(_G)  # G's nonzeros scattered into the array that ``ranges`` holds
        return ranges


def evaluated_ranges(step: BoundFunction, rate_rows: RateRows | None,
                     limits: JointRangeLimit) -> LinearisedRanges:
    """The ranges of the evaluated ``step``, softened by ``limits`` (its soft wall).

    ``G`` and the rooms are read in place (valid until the step function's next evaluation).

    Args:
        step: The evaluated step function.
        rate_rows: Where each row's structural nonzeros lie among those of ``G_ranges``
            (:func:`.frame_problem.rate_rows`), or None.
        limits: The ranges of motion.
    """
    if rate_rows is None:
        return limits.softened(LinearisedRanges(step.output(_G), step.vectors(_UP, 2)))
    return limits.softened(rate_rows.ranges(step), rate_rows.still(step.nonzeros(_G)))


class StepRangeRows:
    """The rows of the angles near a limit at a configuration, from the step function.

    :meth:`.limits.JointRangeLimit.inequality` (the same rows, to rounding) without its NumPy
    linearisation: one evaluation of the step function, its task weights 0 (its objective is
    not read). The one with the contact points' sites only (when there is one, else all of
    them), which the Gauss-Newton steps of a body with contact points and no site target have
    just run: its code is warm (on the real walk a call of the full one took 160 us (CPU)
    after the full one's steps against 200 us for the one without sites, whose code is rarely
    run; the same numbers, bit for bit). It overwrites that function's outputs: call it after
    the frame's steps.

    Args:
        kinematics: The compiled step function.
        geometry: Its geometry input.
        rate_rows: As :func:`evaluated_ranges`.
        limits: The ranges of motion.
        segments: Number of tracked segments (orientation targets).
    """

    def __init__(self, kinematics: CompiledKinematics, geometry: np.ndarray,
                 rate_rows: RateRows | None, limits: JointRangeLimit, segments: int) -> None:
        self.kinematics = kinematics
        self.geometry = geometry
        self.rate_rows = rate_rows
        self.limits = limits
        joints = len(limits.lower)
        self._targets = np.tile(np.eye(3), (segments, 1, 1))  # any rotations: weighed 0
        self._references = np.tile(np.eye(3), (joints, 1, 1))
        self._w_orient = np.zeros(3 * segments)
        self._w_posture = np.zeros(3 * joints)
        for kept in (self._targets, self._references, self._w_orient, self._w_posture):
            read_only(kept)  # left in the step function's slots while they stand

    def inequality(self, configuration: Configuration) -> Inequality:
        """Rows ``G dq <= h`` for the angles near or beyond a limit at ``configuration``."""
        limits = self.limits
        step = self.kinematics.evaluate(configuration.q, self._targets, self.geometry,
                                        self._w_orient, self._w_posture, self._references,
                                        (limits.lower, limits.upper), sites=None)
        ranges = evaluated_ranges(step, self.rate_rows, limits)
        return ranges.inequality(*ranges.near(limits.margin))
