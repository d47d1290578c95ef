"""The step's QP in the least-distance form against DAQP on the problem as it is (issue #20)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import daqp
import numpy as np
import pytest

import ikfusion.ik.qp_backends as backends
from ikfusion.ik.equality_qp import equality_optimum
from ikfusion.ik.least_distance import COUNTS, EQUALITY, identity, least_distance_daqp, senses
from ikfusion.model import HumanModel

N = 30


def _problem(rng: np.random.Generator, bounds: bool) -> tuple[np.ndarray | None, ...]:
    """A strictly convex QP ``(H, c, G, h, A, b, lb, ub)``: 6 equality rows, 10 inequality
    rows and optionally bounds, some of them cutting through the unconstrained optimum."""
    M = rng.standard_normal((N, N))
    H = M @ M.T + 0.1 * np.eye(N)
    c = 3.0 * rng.standard_normal(N)
    A = rng.standard_normal((6, N))
    b = rng.standard_normal(6)
    G = rng.standard_normal((10, N))
    h = rng.uniform(-0.5, 1.0, 10)
    lb, ub = (-np.full(N, 0.4), np.full(N, 0.4)) if bounds else (None, None)
    return H, c, G, h, A, b, lb, ub


def _as_given(*problem: np.ndarray | None) -> tuple[np.ndarray | None, bool]:
    return backends.daqp_as_given(daqp, 1000, *problem)


@pytest.mark.parametrize("bounds", [False, True])
@pytest.mark.parametrize("seed", range(6))
def test_the_step_and_its_binding_rows_are_daqps(seed: int, bounds: bool) -> None:
    problem = _problem(np.random.default_rng(seed), bounds)
    H_before = problem[0].copy()  # type: ignore[union-attr]
    solved = least_distance_daqp(daqp, 1000, *problem)
    assert solved is not None
    x, binding = solved
    expected, expected_binding = _as_given(*problem)
    assert expected is not None
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-9)
    assert binding == expected_binding
    H, _, G, h, A, b, lb, ub = problem
    np.testing.assert_allclose(A @ x, b, atol=1e-9)  # type: ignore[operator]
    assert np.all(G @ x <= h + 1e-6)  # type: ignore[operator]
    if bounds:
        assert np.all(x >= lb - 1e-6) and np.all(x <= ub + 1e-6)  # type: ignore[operator]
    np.testing.assert_array_equal(H, H_before)  # the Hessian is left alone
    np.testing.assert_array_equal(identity(N), np.eye(N))  # and so is the shared identity
    rows = len(h) + len(b) + (N if bounds else 0)  # type: ignore[arg-type]
    fresh = np.zeros(rows, dtype=np.intc)
    fresh[rows - len(b):] = EQUALITY  # type: ignore[arg-type]
    np.testing.assert_array_equal(senses(rows, rows - len(b)), fresh)  # and the shared senses


@pytest.mark.parametrize("bounds", [False, True])
def test_the_shared_identity_is_not_factored_and_gives_the_same_step(rng, bounds: bool) -> None:
    """The projection's ``H = I`` (the shared identity) skips LAPACK: the very numbers of a
    separate identity, which LAPACK factors (the closed form's too)."""
    _, _, G, h, A, b, lb, ub = _problem(rng, bounds)
    c = np.zeros(N)
    shared = least_distance_daqp(daqp, 1000, identity(N), c, G, h, A, b, lb, ub)
    factored = least_distance_daqp(daqp, 1000, np.eye(N), c, G, h, A, b, lb, ub)
    assert shared is not None and factored is not None
    assert np.array_equal(shared[0], factored[0]) and shared[1] == factored[1]
    x, expected = equality_optimum(identity(N), c, A, b), equality_optimum(np.eye(N), c, A, b)
    assert x is not None and expected is not None and np.array_equal(x, expected)


def test_a_hessian_that_is_not_positive_definite_goes_to_daqp_as_given(rng) -> None:
    H, c, G, h, A, b, lb, ub = _problem(rng, bounds=True)
    H = np.diag(np.r_[np.ones(N - 1), -1.0])  # indefinite: no Cholesky factor
    assert least_distance_daqp(daqp, 1000, H, c, G, h, A, b, lb, ub) is None
    before = COUNTS.fallbacks
    x, _ = backends.call_daqp(1000, H, c, G, h, A, b, lb, ub)
    assert COUNTS.fallbacks == before + 1  # counted, never silent
    expected, _ = _as_given(H, c, G, h, A, b, lb, ub)
    assert (x is None) == (expected is None)


def _compared(differences: list[float],
              bindings: list[tuple[bool, bool]],
              natives: list[bool] | None = None) -> Callable[..., Any]:
    """``least_distance_daqp`` (on the native tree factor when the solver passes it: recorded
    in ``natives``) that also solves each problem as given and records the largest difference
    of the steps, and whether a row binds both ways."""
    def solve(module: Any, iterations: int, *problem: np.ndarray | None,
              native: Any = None) -> Any:
        if natives is not None:
            natives.append(native is not None)
        solved = least_distance_daqp(module, iterations, *problem, native=native)
        expected, expected_binding = _as_given(*problem)
        assert solved is not None and expected is not None
        differences.append(float(np.abs(solved[0] - expected).max()))
        bindings.append((solved[1], expected_binding))
        return solved
    return solve


def test_every_qp_of_a_simulated_walk_is_daqps(human: HumanModel, monkeypatch) -> None:
    """The contact frames' QPs of the 17-sensor walk (feet planted, floor and range rows
    binding in runs of steps, the velocity bounds in some)."""
    from ikfusion.ik import Solver
    from ikfusion.model import SENSOR_SEGMENTS
    from ikfusion.sim.gait import GaitParameters, generate_gait
    from ikfusion.sim.truth import orientation_frames

    truth = generate_gait(human, GaitParameters(duration=2.5, stand=0.5), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    differences: list[float] = []
    bindings: list[tuple[bool, bool]] = []
    monkeypatch.setattr(backends, "least_distance_daqp", _compared(differences, bindings))
    Solver(human, contacts=True).solve(frames)
    assert all(ours == theirs for ours, theirs in bindings)
    assert sum(ours for ours, _ in bindings) >= 10  # rows bind in many of them
    assert max(differences) < 1e-9, max(differences)


def test_every_qp_of_the_real_walk_is_daqps(shared_data: Path, tmp_path: Path, human: HumanModel,
                                            monkeypatch) -> None:
    """The 8-sensor real walk (2505 frames): every QP DAQP solves, solved both ways (most of
    them on the native tree factor when the kernel is built: 531 of 668)."""
    from ikfusion.cli import main
    from ikfusion.ik.tree_solve import tree_closed_form

    trial = shared_data / "xsens" / "opensense_walk"
    differences: list[float] = []
    bindings: list[tuple[bool, bool]] = []
    natives: list[bool] = []
    monkeypatch.setattr(backends, "least_distance_daqp",
                        _compared(differences, bindings, natives))
    assert main(["solve", "--imu", str(trial), "--map", str(trial / "myIMUMappings.xml"),
                 "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert all(ours == theirs for ours, theirs in bindings)
    assert sum(ours for ours, _ in bindings) >= 100
    assert max(differences) < 1e-9, max(differences)
    assert sum(natives) >= (400 if tree_closed_form(human.model) is not None else 0)
