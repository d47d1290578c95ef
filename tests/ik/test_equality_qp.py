"""The closed-form step (no inequality binds) against DAQP, and its fall-backs."""

from __future__ import annotations

import numpy as np
import pytest

import ikfusion.ik.qp as qp_module
from ikfusion.ik.equality_qp import equality_optimum, independent_solve
from ikfusion.ik.projection import minimum_norm_step
from ikfusion.ik.qp import QpProblem, solve_qp
from ikfusion.ik.settings import SolverSettings

N = 30


def _problem(rng: np.random.Generator, h_offset: float) -> QpProblem:
    """A strictly convex QP with 6 equality rows and 10 inequality rows ``G x <= h``."""
    M = rng.standard_normal((N, N))
    H = M @ M.T + 0.1 * np.eye(N)
    c = rng.standard_normal(N)
    A = rng.standard_normal((6, N))
    b = rng.standard_normal(6)
    G = rng.standard_normal((10, N))
    x_free = equality_optimum(H, c, A, b)
    assert x_free is not None
    return QpProblem(H, c, G, G @ x_free + h_offset, A, b)


def _daqp(p: QpProblem) -> np.ndarray:
    x = qp_module._call_daqp(1000, p.H, p.c, p.G, p.h, p.A, p.b, p.lb, p.ub)
    assert x is not None
    return x


@pytest.mark.parametrize("seed", range(5))
def test_a_step_touching_no_limit_is_solved_without_daqp_and_equals_it(seed: int,
                                                                       monkeypatch) -> None:
    problem = _problem(np.random.default_rng(seed), h_offset=0.5)  # every row slack
    expected = _daqp(problem)
    monkeypatch.setattr(qp_module, "_call_daqp", lambda *a: pytest.fail("DAQP was called"))
    settings = SolverSettings.load()
    x = solve_qp(problem, "daqp", settings.qp).dq
    np.testing.assert_allclose(x, expected, atol=1e-8)
    np.testing.assert_allclose(problem.A @ x, problem.b, atol=1e-10)


@pytest.mark.parametrize("seed", range(5))
def test_a_step_at_a_limit_is_left_to_daqp(seed: int) -> None:
    problem = _problem(np.random.default_rng(seed), h_offset=0.0)
    problem.h[:3] -= 0.3  # three rows cut through the equality-constrained optimum
    settings = SolverSettings.load()
    x = solve_qp(problem, "daqp", settings.qp).dq
    np.testing.assert_allclose(x, _daqp(problem), atol=1e-8)
    assert np.all(problem.G @ x <= problem.h + 1e-9)
    assert np.max(problem.G[:3] @ x - problem.h[:3]) > -1e-9  # a cutting row binds


def test_dependent_rows_are_not_solved_through_their_gram_matrix(rng) -> None:
    A = rng.standard_normal((6, N))
    A[5] = A[3] - 2.0 * A[1]  # two points of one rigid segment give such rows
    assert independent_solve(A @ A.T, rng.standard_normal(6)) is None
    assert equality_optimum(np.eye(N), np.zeros(N), A, rng.standard_normal(6)) is None


@pytest.mark.parametrize("dependent", [False, True])
def test_the_projection_step_is_the_least_squares_minimum_norm_step(rng,
                                                                    dependent: bool) -> None:
    A = rng.standard_normal((9, N))
    if dependent:
        A[8] = A[0] + A[4]
    b = A @ rng.standard_normal(N)
    np.testing.assert_allclose(minimum_norm_step(A, b),
                               np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-10)
