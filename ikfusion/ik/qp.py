"""The Gauss-Newton step as one quadratic program, built in one place and inspectable.

    minimise    1/2 dq^T H dq + c^T dq
    subject to  G dq <= h,   A dq = b,   lb <= dq <= ub

``H`` and ``c`` sum the tasks' ``J^T W J`` and ``J^T W e`` plus a small Levenberg-Marquardt
damping. When the constraints cannot all hold (a planted foot out of reach within the ranges of
motion), :func:`solve_qp` solves a relaxed problem in which every equality and inequality row
has a slack variable with a heavy quadratic penalty, and reports that it did. With DAQP, a step
whose equality-constrained optimum already satisfies every inequality (most steps) is solved in
closed form (:mod:`.equality_qp`) and DAQP is called only when a limit binds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from .configuration import Configuration
from .equality_qp import ClosedFormHint, equality_optimum, satisfies
from .fast_math import add_to_diagonal, sum_of
from .limits.base import Equality, Inequality
from .qp_backends import call_daqp, installed, qpsolvers_module, solver_options
from .tasks.base import Task
from .tree_solve import NOT_FINITE, NOT_TREE, SOLVED, TreeClosedForm


@dataclass(frozen=True)
class QpSettings:
    """How the QP backends are run (from ``configs/solver.yaml``, section ``qp``).

    Attributes:
        max_iterations: Most active-set iterations DAQP / ProxQP may take on one step: a step
            of this size (tens of variables and rows) needs far fewer, so reaching it means a
            broken problem, which then fails instead of running on.
        slack_weight: Quadratic penalty of the relaxed problem's slack [1/m^2 or 1/rad^2].
        relaxed_slack_scale: The penalty is scaled by this when the first relaxation fails
            (a heavy penalty makes the relaxed problem ill-conditioned).
        osqp_tolerance: OSQP's absolute and relative tolerance.
        osqp_max_iterations: OSQP's iteration limit.
    """

    max_iterations: int
    slack_weight: float
    relaxed_slack_scale: float
    osqp_tolerance: float
    osqp_max_iterations: int


@dataclass
class QpProblem:
    """One tangent-space QP (dense matrices)."""

    H: np.ndarray
    c: np.ndarray
    G: np.ndarray
    h: np.ndarray
    A: np.ndarray
    b: np.ndarray
    lb: np.ndarray | None = None
    ub: np.ndarray | None = None
    #: H, c, G, h, A and b as consecutive views of this one array (:class:`QpBuffer`), so that
    #: their finite check is one sum; None when they are separate arrays.
    packed: np.ndarray | None = None
    #: The native closed-form step of :attr:`packed` (:mod:`.tree_solve`), or None.
    tree: TreeClosedForm | None = None


@dataclass
class QpSolution:
    """A QP step.

    Attributes:
        dq: Tangent step (nv,).
        relaxed: True when the constraints were relaxed with penalised slack.
        slack: Largest slack used [m or rad] (0 when not relaxed).
    """

    dq: np.ndarray
    relaxed: bool = False
    slack: float = 0.0


def build_qp(configuration: Configuration, tasks: Sequence[Task],
             inequalities: Sequence[Inequality], equalities: Sequence[Equality],
             bounds: tuple[np.ndarray, np.ndarray] | None,
             damping: float) -> QpProblem:
    """Assemble the QP of one Gauss-Newton step at ``configuration`` from task objects."""
    nv = configuration.model.nv
    H = np.zeros((nv, nv))
    c = np.zeros(nv)
    for task in tasks:
        task.add_objective(configuration, H, c)
    return assemble_qp(H, c, inequalities, equalities, bounds, damping)


def assemble_qp(H: np.ndarray, c: np.ndarray, inequalities: Sequence[Inequality],
                equalities: Sequence[Equality],
                bounds: tuple[np.ndarray, np.ndarray] | None,
                damping: float) -> QpProblem:
    """A :class:`QpProblem` from an accumulated objective and constraint blocks."""
    nv = H.shape[0]
    H.flat[::nv + 1] += damping  # the diagonal
    ineq = [i for i in inequalities if len(i.h)]
    eq = [e for e in equalities if len(e.b)]
    G = np.vstack([i.G for i in ineq]) if ineq else np.zeros((0, nv))
    h = np.concatenate([i.h for i in ineq]) if ineq else np.zeros(0)
    A = np.vstack([e.A for e in eq]) if eq else np.zeros((0, nv))
    b = np.concatenate([e.b for e in eq]) if eq else np.zeros(0)
    lb, ub = bounds if bounds is not None else (None, None)
    return QpProblem(H, c, G, h, A, b, lb, ub)


class QpBuffer:
    """One preallocated array holding a step's ``H, c, G, h, A, b``, reused step after step.

    :meth:`assemble` builds the same problem as :func:`assemble_qp` (the same numbers in the
    same layout) into views of the buffer, which :func:`solve_qp` checks for NaN and
    infinities with one sum. A problem assembled here is overwritten by the next one.

    Args:
        nv: Tangent-space dimension (the number of variables).
        tree: The native closed-form step its problems are solved with first (DAQP), or None.
    """

    def __init__(self, nv: int, tree: TreeClosedForm | None = None) -> None:
        self.nv = nv
        self.tree = tree
        self._flat = np.empty(nv * nv + nv)
        # (m_in, m_eq) -> the packed buffer and its views H, c, G, h, A, b: made once per size
        self._views: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}

    def assemble(self, H: np.ndarray, c: np.ndarray, inequalities: Sequence[Inequality],
                 equalities: Sequence[Equality], bounds: tuple[np.ndarray, np.ndarray] | None,
                 damping: float) -> QpProblem:
        """:func:`assemble_qp` into the buffer (``H`` is copied, not changed)."""
        m_in = sum(len(i.h) for i in inequalities)
        m_eq = sum(len(e.b) for e in equalities)
        problem = self.views(m_in, m_eq)
        np.copyto(problem.H, H)
        add_to_diagonal(problem.H, damping)
        np.copyto(problem.c, c)
        _stacked_rows(problem.G, problem.h, [(i.G, i.h) for i in inequalities if len(i.h)])
        _stacked_rows(problem.A, problem.b, [(e.A, e.b) for e in equalities if len(e.b)])
        problem.lb, problem.ub = bounds if bounds is not None else (None, None)
        return problem

    def views(self, m_in: int, m_eq: int) -> QpProblem:
        """A problem of ``m_in`` inequality and ``m_eq`` equality rows in the buffer.

        Its arrays are views of the buffer, uninitialised (the caller fills every entry), with
        no bounds; overwritten by the next call.
        """
        made = self._views.get((m_in, m_eq))
        if made is None:
            made = self._views[m_in, m_eq] = self._made_views(m_in, m_eq)
        packed, H, c, G, h, A, b = made
        return QpProblem(H, c, G, h, A, b, packed=packed, tree=self.tree)

    def _made_views(self, m_in: int, m_eq: int) -> tuple[np.ndarray, ...]:
        """The packed buffer of a problem of this size and its six views (:meth:`views`)."""
        nv = self.nv
        size = nv * nv + nv + (m_in + m_eq) * (nv + 1)
        if len(self._flat) < size:  # a larger buffer: the views of the old one are dropped
            self._flat = np.empty(max(size, 2 * len(self._flat)))
            self._views.clear()
        packed = self._flat[:size]
        c_at = nv * nv
        G_at = c_at + nv
        h_at = G_at + m_in * nv
        A_at = h_at + m_in
        b_at = A_at + m_eq * nv
        return (packed, packed[:c_at].reshape(nv, nv), packed[c_at:G_at],
                packed[G_at:h_at].reshape(m_in, nv), packed[h_at:A_at],
                packed[A_at:b_at].reshape(m_eq, nv), packed[b_at:])


def _stacked_rows(M: np.ndarray, v: np.ndarray,
                  blocks: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Row blocks ``(M_i, v_i)`` stacked into ``M`` and ``v`` (as many rows as they hold)."""
    row = 0
    for block, values in blocks:
        k = len(values)
        M[row:row + k] = block
        v[row:row + k] = values
        row += k


def _call(backend: str, settings: QpSettings, H: np.ndarray, c: np.ndarray,
          G: np.ndarray | None, h: np.ndarray | None, A: np.ndarray | None,
          b: np.ndarray | None, lb: np.ndarray | None, ub: np.ndarray | None,
          hint: ClosedFormHint | None = None, closed_form: bool = True,
          native: tuple[TreeClosedForm, np.ndarray] | None = None) -> np.ndarray | None:
    """The step by ``backend``; DAQP: closed form first unless ``hint``/``closed_form`` skip."""
    if not installed(backend):
        raise SolverError(
            f"QP backend {backend!r} is not installed; available: "
            f"{', '.join(qpsolvers_module().available_solvers)}")
    if backend == "daqp":
        # most steps touch no limit: their optimum in closed form, DAQP when one binds
        if closed_form and (hint is None or not hint.skip):
            x = equality_optimum(H, c, A, b)
            if x is not None and satisfies(x, G, h, lb, ub):
                return x
        x, binding = call_daqp(settings.max_iterations, H, c, G, h, A, b, lb, ub, native)
        if hint is not None:
            hint.skip = binding
        return x
    qpsolvers = qpsolvers_module()
    try:
        x = qpsolvers.solve_qp(H, c, G, h, A, b, lb, ub, solver=backend,
                               **solver_options(backend, settings))
    except (ValueError, qpsolvers.QPError):
        return None
    return None if x is None or not np.all(np.isfinite(x)) else np.asarray(x)


#: Backends that solve these small dense QPs exactly (OSQP is approximate at its defaults).
_EXACT_BACKENDS = ("daqp", "proxqp")


def solve_unrelaxed(problem: QpProblem, backend: str, settings: QpSettings,
                    hint: ClosedFormHint | None = None, answer: int | None = None
                    ) -> QpSolution | None:
    """The step with every constraint held, or None when no exact backend finds one.

    :func:`solve_qp` without its relaxation (``answer``: the kernel's, when known): for a
    caller that, when the constraints cannot all hold, changes the problem rather than relaxing.

    Raises:
        SolverError: A problem holding NaN or infinite numbers (no backend is tried).
    """
    p = problem
    native = p.tree is not None and p.packed is not None and backend == "daqp" and \
        (hint is None or not hint.skip)
    if not native or p.lb is not None or p.ub is not None:
        _check_finite(p)
    closed_form = True
    if native:  # the finite check and the closed form in one native call (_call's in NumPy)
        assert p.tree is not None and p.packed is not None
        answer = p.tree.solve(p.packed, len(p.h), len(p.b)) if answer is None else answer
        if answer == NOT_FINITE:
            _check_finite(p)  # names what is not finite (an overflowing sum of finite numbers
            # passes, as it does there)
        if answer == SOLVED and satisfies(p.tree.x, None, None, p.lb, p.ub):
            return QpSolution(p.tree.x.copy())
        closed_form = answer == NOT_TREE
    G = p.G if len(p.h) else None
    h = p.h if len(p.h) else None
    A = p.A if len(p.b) else None
    b = p.b if len(p.b) else None
    x = _call(backend, settings, p.H, p.c, G, h, A, b, p.lb, p.ub, hint, closed_form,
              None if p.tree is None or p.packed is None else (p.tree, p.packed))
    if x is not None:
        return QpSolution(x)
    # A numerical failure on a degenerate but feasible step (a limit active exactly where a
    # planted point holds) is not infeasibility: another exact backend first.
    for other in _EXACT_BACKENDS:
        if other != backend and installed(other):
            x = _call(other, settings, p.H, p.c, G, h, A, b, p.lb, p.ub)
            if x is not None:
                return QpSolution(x)
    return None


def solve_qp(problem: QpProblem, backend: str, settings: QpSettings,
             hint: ClosedFormHint | None = None, answer: int | None = None) -> QpSolution:
    """Solve the step; fall back to the penalised-slack relaxation when it is infeasible.

    Args:
        problem: The step's QP.
        backend: The QP backend (qpsolvers name) tried first.
        settings: Iteration limits, tolerances and the slack penalties.
        hint: Whether DAQP's closed-form try is skipped (:class:`.equality_qp.ClosedFormHint`,
            updated by this step); None: always tried.
        answer: The kernel's answer on this problem, when known (:func:`solve_unrelaxed`).

    Raises:
        SolverError: A problem holding NaN or infinite numbers (a target or the pose is not
            finite: no backend is tried), or when even the relaxed problem fails with every
            backend (never silently; the solver then keeps the previous pose for that frame
            and says so).
    """
    p = problem
    solution = solve_unrelaxed(p, backend, settings, hint, answer)
    if solution is not None:
        return solution
    # Infeasible (or a numerical failure): relax, with a milder penalty and another backend
    # before giving up, since a heavy penalty makes the relaxed problem ill-conditioned.
    heavy = settings.slack_weight
    mild = heavy * settings.relaxed_slack_scale
    attempts = [(backend, heavy), (backend, mild)]
    attempts += [(other, mild) for other in ("proxqp", "daqp")
                 if other != backend and installed(other)]
    for name, weight in attempts:
        solution = _solve_relaxed(p, name, weight, settings)
        if solution is not None:
            return solution
    raise SolverError(f"the relaxed IK step failed with every backend tried "
                      f"({', '.join(a for a, _ in attempts)}; {p.H.shape[0]} variables, "
                      f"{len(p.h)} inequalities, {len(p.b)} equalities)")


def _check_finite(p: QpProblem) -> None:
    """Raise a clear error instead of handing a backend NaN or infinite numbers."""
    # One sum per array (or one for a packed problem) is finite when every entry is (and when
    # it is not, the slow path below names the culprits; absurd finite values overflowing the
    # sum land there too).
    total = sum_of(p.packed) if p.packed is not None else (
        sum_of(p.H) + sum_of(p.c) + sum_of(p.h) + sum_of(p.b) + sum_of(p.G) + sum_of(p.A))
    if math.isfinite(total) and not (p.lb is not None and np.isnan(p.lb.sum())) \
            and not (p.ub is not None and np.isnan(p.ub.sum())):
        return
    bad = [name for name, m in (("H", p.H), ("c (targets)", p.c), ("h (inequalities)", p.h),
                                ("b (equalities)", p.b), ("G", p.G), ("A", p.A))
           if not np.isfinite(m).all()]
    bad += [name for name, m in (("lb", p.lb), ("ub", p.ub)) if m is not None
            and np.isnan(m).any()]
    if bad:
        raise SolverError(
            f"the IK step holds NaN or infinite numbers in {', '.join(bad)}: a target or the "
            "pose is not finite (check the input motion for NaN or absurd values)")


def _solve_relaxed(p: QpProblem, backend: str, slack_weight: float,
                   settings: QpSettings) -> QpSolution | None:
    """Every constraint row gets a slack ``s`` with cost ``slack_weight/2 * s^2``."""
    nv = p.H.shape[0]
    m_in, m_eq = len(p.h), len(p.b)
    n = nv + m_in + m_eq
    H = np.zeros((n, n))
    H[:nv, :nv] = p.H
    H[np.arange(nv, n), np.arange(nv, n)] = slack_weight
    c = np.concatenate([p.c, np.zeros(m_in + m_eq)])
    G = np.hstack([p.G, -np.eye(m_in), np.zeros((m_in, m_eq))]) if m_in else None
    A = np.hstack([p.A, np.zeros((m_eq, m_in)), -np.eye(m_eq)]) if m_eq else None
    lb = np.concatenate([p.lb if p.lb is not None else np.full(nv, -np.inf),
                         np.zeros(m_in), np.full(m_eq, -np.inf)])
    ub = np.concatenate([p.ub if p.ub is not None else np.full(nv, np.inf),
                         np.full(m_in + m_eq, np.inf)])
    x = _call(backend, settings, H, c, G, p.h if m_in else None, A, p.b if m_eq else None, lb,
              ub)
    if x is None:
        return None
    slack = float(np.max(np.abs(x[nv:]))) if n > nv else 0.0
    return QpSolution(x[:nv], relaxed=True, slack=slack)
