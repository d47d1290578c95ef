"""Projection of a solved frame onto its contacts and the floor.

The Gauss-Newton loop may stop while large steps (a target out of reach) still leave a
second-order error on planted points; :func:`project_on_contacts` removes it, so planted feet
never slide. :func:`place_on_floor` puts the first frame's body on the floor.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from ..errors import SolverError
from .configuration import Configuration
from .contact_projection import HELD, TO_QP, NativeProjection
from .contact_projection import native_projection as native_projection  # (the solver's)
from .equality_qp import ClosedFormHint, independent_solve
from .fast_math import min_of
from .least_distance import identity
from .limits import ContactConstraint, FloorLimit
from .limits.base import Inequality
from .qp import QpSettings, assemble_qp, solve_qp


class RangeRows(Protocol):
    """The ranges of motion's rows near a limit at a configuration.

    :class:`.limits.JointRangeLimit` (NumPy) or :class:`.step_ranges.StepRangeRows` (the
    compiled step function, the same rows to rounding).
    """

    def inequality(self, configuration: Configuration) -> Inequality:
        """Rows ``G dq <= h`` for the angles near or beyond a limit at ``configuration``."""
        ...


def project_on_contacts(conf: Configuration, contact: ContactConstraint, floor: FloorLimit,
                        ranges: RangeRows, contact_frames: Sequence[int],
                        tolerance: float, max_steps: int, backend: str,
                        qp: QpSettings, native: NativeProjection | None = None) -> bool:
    """Remove the linearisation residual of the contacts from ``conf`` (in place).

    A few minimum-norm steps on the contact rows (or, if those do not converge or leave a
    point below the floor, QPs with only the constraints, the ranges, the floor and
    ``1/2 |dq|^2``) bring every planted point within ``tolerance`` [m] of its anchor.

    Args:
        conf: The solved configuration; updated to the projected one.
        contact: The contact constraint, anchors set.
        floor: The floor limit.
        ranges: The ranges of motion (their rows near a limit).
        contact_frames: Frame index of each contact point.
        tolerance: The constraint tolerance [m].
        max_steps: At most this many steps of each kind.
        backend: QP backend.
        qp: QP settings.
        native: The minimum-norm steps in native code (:mod:`.contact_projection`), used
            when made for ``conf`` and the contacts are along the world axes; None: this
            function's own loop.

    Returns:
        True when a step had to be relaxed (or no backend could solve one).
    """
    if not contact_frames:
        return False
    q_start = conf.q  # read-only: update() replaces it
    if native is not None and native.conf is conf and contact.world_rows() is not None:
        answer = native.project(contact, floor, tolerance, max_steps)
        if answer == HELD:
            return False
        if answer == TO_QP:
            conf.update(q_start)
            # its first QP's closed-form try is the minimum-norm step: skipped when that
            # crossed a floor row (it would fail; DAQP then solves the same QP as before)
            return project_with_limits(conf, contact, floor, ranges, contact_frames,
                                       tolerance, max_steps, backend, qp,
                                       ClosedFormHint(skip=bool(native.plan.floor_crossed)))
    for _ in range(max_steps):  # the residual is second order: minimum-norm steps suffice
        P = conf.positions(contact_frames)
        if not contact.slides(P, tolerance):
            if above_floor(P, floor.floor_z, tolerance):
                return False
            break
        # the rows of every point (those not held are left out) from this configuration's
        # positions and Jacobians: the same rows as contact.equality, in fewer operations
        A, b = contact.rows(P, conf.linear_jacobians(contact_frames))
        conf.update(conf.integrate(minimum_norm_step(A, b)))
    conf.update(q_start)
    return project_with_limits(conf, contact, floor, ranges, contact_frames, tolerance,
                               max_steps, backend, qp)


def project_with_limits(conf: Configuration, contact: ContactConstraint, floor: FloorLimit,
                        ranges: RangeRows, contact_frames: Sequence[int], tolerance: float,
                        max_steps: int, backend: str, qp: QpSettings,
                        first: ClosedFormHint | None = None) -> bool:
    """:func:`project_on_contacts`' QPs: only the constraints, the ranges, the floor, ``|dq|^2``.

    The contact and floor rows come from the points' positions and Jacobians (the same rows
    as :meth:`.ContactConstraint.equality` and :meth:`.FloorLimit.inequality`); ``H`` is the
    shared identity, whose factorisations the solvers skip (:func:`.least_distance.identity`).
    Arguments and return as :func:`project_on_contacts` (``conf`` updated in place);
    ``first``: the first QP's :class:`.equality_qp.ClosedFormHint` (None: its closed form tried).
    """
    relaxed, hint = False, first
    for _ in range(max_steps):
        P = conf.positions(contact_frames)
        if not contact.slides(P, tolerance):
            break
        J = conf.linear_jacobians(contact_frames)  # valid until the next update
        # assembled on a zero H (the shared identity is never written), then H = I
        problem = assemble_qp(np.zeros((conf.model.nv, conf.model.nv)), np.zeros(conf.model.nv),
                              [ranges.inequality(conf), floor.rows(P, J)],
                              [contact.rows(P, J)], None, 0.0)
        problem.H = identity(conf.model.nv)
        try:
            solution = solve_qp(problem, backend, qp, hint)
        except SolverError:
            return True
        relaxed, hint = relaxed or solution.relaxed, None
        conf.update(conf.integrate(solution.dq))
    return relaxed


def minimum_norm_step(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The shortest ``dq`` (nv,) with ``A dq = b`` for contact rows ``A`` (m, nv), ``b`` (m,) [m].

    ``dq = A^T y`` with ``A A^T y = b``, a small (m, m) system (several times cheaper than a
    least-squares solve of the wide one); (nearly) dependent rows get the least-squares
    solution instead.
    """
    y = independent_solve(A @ A.T, b) if len(b) else None
    if y is None:
        return np.asarray(np.linalg.lstsq(A, b, rcond=None)[0])
    return A.T.dot(y)  # BLAS's gemv as A.T @ y, without matmul's dispatch


def above_floor(p_contacts: np.ndarray, floor_z: float, tolerance: float) -> bool:
    """No contact point (c, 3) [m] below the floor ``floor_z`` [m] by more than ``tolerance``."""
    return bool(min_of(p_contacts[:, 2]) >= floor_z - tolerance)


def place_on_floor(conf: Configuration, q: np.ndarray, contact_frames: Sequence[int],
                   floor_z: float) -> np.ndarray:
    """``q`` lifted or lowered so that its lowest contact point is on the floor ``floor_z`` [m].

    For the first frame, which has no anchors yet. ``conf`` is set to ``q`` (not moved).
    """
    conf.update(q)
    if not contact_frames:
        return q
    z = conf.positions(contact_frames)[:, 2]
    q = q.copy()
    q[2] += floor_z - z.min()
    return q
