"""The closed-form step (no inequality binds) against DAQP, and its fall-backs."""

from __future__ import annotations

import numpy as np
import pytest

import ikfusion.ik.qp as qp_module
from ikfusion.ik.equality_qp import ClosedFormHint, equality_optimum, independent_solve
from ikfusion.ik.projection import minimum_norm_step
from ikfusion.ik.qp import QpProblem, solve_qp
from ikfusion.ik.settings import SolverSettings
from ikfusion.model import HumanModel

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
    x, _ = qp_module.call_daqp(1000, p.H, p.c, p.G, p.h, p.A, p.b, p.lb, p.ub)
    assert x is not None
    return x


@pytest.mark.parametrize("seed", range(5))
def test_a_step_touching_no_limit_is_solved_without_daqp_and_equals_it(seed: int,
                                                                       monkeypatch) -> None:
    problem = _problem(np.random.default_rng(seed), h_offset=0.5)  # every row slack
    expected = _daqp(problem)
    monkeypatch.setattr(qp_module, "call_daqp", lambda *a: pytest.fail("DAQP was called"))
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


@pytest.mark.parametrize("seed", range(3))
def test_after_a_binding_limit_the_next_step_goes_to_daqp_at_once(seed: int,
                                                                  monkeypatch) -> None:
    """Issue #20: a limit that binds in one step mostly binds in the next, where the
    closed-form try only costs time. After a step whose limit binds the hint skips the try (the
    same optimum, DAQP's); after one where none binds it tries the closed form again."""
    rng = np.random.default_rng(seed)
    settings = SolverSettings.load().qp
    hint = ClosedFormHint()
    at_limit = _problem(rng, h_offset=0.0)
    at_limit.h[:3] -= 0.3  # three rows cut through the equality-constrained optimum
    solve_qp(at_limit, "daqp", settings, hint)
    assert hint.skip
    tries: list[int] = []
    original = qp_module.equality_optimum

    def counted(*args: np.ndarray | None) -> np.ndarray | None:
        tries.append(1)
        return original(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(qp_module, "equality_optimum", counted)
    x = solve_qp(at_limit, "daqp", settings, hint).dq
    assert not tries and hint.skip
    np.testing.assert_allclose(x, _daqp(at_limit), atol=1e-8)
    free = _problem(rng, h_offset=0.5)  # every row slack: DAQP's optimum binds none
    x = solve_qp(free, "daqp", settings, hint).dq
    assert not tries and not hint.skip
    np.testing.assert_allclose(x, original(free.H, free.c, free.A, free.b), atol=1e-8)
    solve_qp(free, "daqp", settings, hint)
    assert tries == [1]  # tried again, and it holds


def test_a_walk_skips_most_closed_form_tries_that_would_fail(human: HumanModel,
                                                             monkeypatch) -> None:
    """On a walk (feet planted on the floor, its rows binding over runs of steps) most DAQP
    solves come without a failed closed-form try before them. Before (59924df), every DAQP
    solve followed one (18 of 18 on this walk)."""
    from ikfusion.ik import Solver
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=2.5, stand=0.5), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    counts = {"failed tries": 0, "daqp": 0}
    satisfies, call_daqp = qp_module.satisfies, qp_module.call_daqp

    def checked(*args: np.ndarray | None) -> bool:
        held = satisfies(*args)  # type: ignore[arg-type]
        counts["failed tries"] += not held
        return held

    def daqp(*args: np.ndarray | int | None) -> tuple[np.ndarray | None, bool]:
        counts["daqp"] += 1
        return call_daqp(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(qp_module, "satisfies", checked)
    monkeypatch.setattr(qp_module, "call_daqp", daqp)
    Solver(human, contacts=True).solve(frames)
    assert counts["daqp"] >= 10  # limits bind on this walk
    assert counts["failed tries"] < 0.5 * counts["daqp"], counts
