"""The lazy active set: a step's QP holds only the limit rows it is likely to need.

Few of the ranges of motion and velocity bounds are ever active, and every row costs the QP
solver time. So a step's QP holds the limits of the angles near a limit (and the floor) and no
velocity bounds; a step that would cross another limit or a bound is solved again with those
rows. A relaxed step is solved again with every row.

The common step (the native closed form solves the QP, no left-out row crossed, no bound
passed) is taken in one native call (:meth:`.tree_solve.TreeClosedForm.step`): the same step
and the same decisions as the loop below, which takes over whenever a row must be added, a
bound passed, or the kernel cannot solve the QP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .equality_qp import ClosedFormHint
from .fast_math import any_true
from .limits import Inequality
from .limits.joint_range import LinearisedRanges
from .qp import QpProblem, QpSettings, QpSolution, solve_qp
from .tree_solve import GOES_ON, SOLVED


@dataclass
class LimitRows:
    """The limit rows of a step: those in its QP and those left out.

    Attributes:
        ranges: The linearised ranges of motion (every row).
        up: (m,) upper limits in the QP.
        down: (m,) lower limits in the QP.
        floor: The floor rows (always in the QP; kept to rebuild it).
        bounds: The velocity bounds on the step (lower, upper) (nv,) [rad or m], or None.
    """

    ranges: LinearisedRanges
    up: np.ndarray
    down: np.ndarray
    floor: Inequality
    bounds: tuple[np.ndarray, np.ndarray] | None


def solve_with_active_set(problem: QpProblem, rows: LimitRows, backend: str,
                          settings: QpSettings, tolerance: float, resolves: int,
                          hint: ClosedFormHint | None = None) -> QpSolution:
    """Solve a step's QP, adding the rows it left out only when the step needs them.

    Args:
        problem: The QP (its inequalities: the ranges in ``rows`` and the floor); changed in
            place when rows are added.
        rows: Its limit rows; ``up`` and ``down`` grow with the rows added.
        backend: QP backend.
        settings: QP settings.
        tolerance: A limit or bound is crossed when the step passes it by more [rad or m].
        resolves: At most this many solves again.
        hint: Whether to skip the closed-form try (:class:`.equality_qp.ClosedFormHint`, kept
            from step to step by the caller); None: always tried.

    Raises:
        SolverError: No backend could solve the QP.
    """
    answer, solution = _native_step(problem, rows, backend, tolerance, resolves, hint)
    if solution is None:  # the kernel's answer (if it ran) not asked for again
        solution = solve_qp(problem, backend, settings, hint, answer)
        if _surely_within(problem, rows, solution, tolerance):  # the loop's first test
            return solution
    elif answer == SOLVED:  # the common step: nothing left out crossed, no bound passed
        return solution
    lb, ub = rows.bounds if rows.bounds is not None else (None, None)
    for _ in range(resolves):
        if solution.relaxed:
            rows.up[:], rows.down[:] = True, True
        crossed_up, crossed_down = rows.ranges.crossed(solution.dq, tolerance)
        crossing = any_true(crossed_up) or any_true(crossed_down)
        if crossing:  # rarely: masked only then
            crossed_up &= ~rows.up
            crossed_down &= ~rows.down
            crossing = any_true(crossed_up) or any_true(crossed_down)
        outside = lb is not None and ub is not None and problem.lb is None and bool(
            any_true(solution.dq < lb - tolerance) or any_true(solution.dq > ub + tolerance))
        if not (solution.relaxed or outside or crossing):
            return solution
        rows.up |= crossed_up
        rows.down |= crossed_down
        ranges = rows.ranges.inequality(rows.up, rows.down)
        problem.G = np.vstack([ranges.G, rows.floor.G])
        problem.h = np.concatenate([ranges.h, rows.floor.h])
        problem.packed = None  # G and h are no longer views of it: checked one by one
        if outside or solution.relaxed:
            problem.lb, problem.ub = lb, ub
        relaxed_before = solution.relaxed
        solution = solve_qp(problem, backend, settings, hint)
        if relaxed_before:
            return solution
    return solution


def _surely_within(problem: QpProblem, rows: LimitRows, solution: QpSolution,
                   tolerance: float) -> bool:
    """The first test of :func:`solve_with_active_set`'s loop in one native call.

    True when the solution is not relaxed, crosses none of the range rows left out and
    passes none of the bounds (tested when the QP has none) by more than ``tolerance``,
    whatever the summation order of the rates (:meth:`.tree_solve.TreeClosedForm.passes_none`):
    the loop would return it at once. False: the loop decides (also without the kernel).
    """
    tree = problem.tree
    if tree is None or solution.relaxed:
        return False
    bounds = rows.bounds if problem.lb is None else None
    if bounds is not None and (bounds[0] is None or bounds[1] is None):
        bounds = None
    return tree.passes_none(solution.dq, rows.ranges, rows.up, rows.down, bounds, tolerance)


def _native_step(problem: QpProblem, rows: LimitRows, backend: str, tolerance: float,
                 resolves: int, hint: ClosedFormHint | None
                 ) -> tuple[int | None, QpSolution | None]:
    """The common step in one native call (:meth:`.tree_solve.TreeClosedForm.step`).

    :func:`.qp.solve_qp`'s closed-form try and the first pass of the loop of
    :func:`solve_with_active_set` on a QP without bounds. Returns ``(SOLVED, the step)`` when
    the closed form solves the QP, crosses no range row left out and passes no bound;
    ``(GOES_ON, the closed form's step)`` when it solves the QP (so :func:`.qp.solve_qp`
    returns it) but the loop must test it; ``(answer, None)`` when :func:`.qp.solve_qp`
    decides (the kernel could not solve the QP: its answer) or ``(None, None)`` (DAQP is due,
    or the QP is not for the kernel: not tried).
    """
    p = problem
    tree = p.tree
    if tree is None or p.packed is None or backend != "daqp" or \
            (hint is not None and hint.skip) or p.lb is not None or p.ub is not None or \
            resolves < 1:
        return None, None
    bounds = rows.bounds
    if bounds is not None and (bounds[0] is None or bounds[1] is None):
        bounds = None
    answer = tree.step(p.packed, len(p.h), len(p.b), rows.ranges, rows.up, rows.down, bounds,
                       tolerance)
    return answer, QpSolution(tree.x.copy()) if answer in (SOLVED, GOES_ON) else None
