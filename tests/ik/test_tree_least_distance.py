"""DAQP's least-distance form on the native tree factor (TreeClosedForm.least_distance_rows)
against the same form on LAPACK's Cholesky factor and DAQP on the problem as it is: the same
binding rows and the same step to rounding, on random tree-pattern QPs and on the solver's
walk; a QP the kernel refuses goes to LAPACK."""

from __future__ import annotations

from typing import Any

import daqp
import numpy as np
import pytest

import ikfusion.ik.least_distance as least_distance
import ikfusion.ik.qp_backends as backends
from ikfusion.ik import Solver
from ikfusion.ik.least_distance import least_distance_daqp
from ikfusion.ik.qp import QpBuffer, QpProblem
from ikfusion.ik.tree_solve import TreeClosedForm, ancestors, column_parents
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames


def _problem(rng: np.random.Generator, model: HumanModel, tree: TreeClosedForm, m_in: int,
             m_eq: int) -> QpProblem:
    """A strictly convex QP with H on the tree's pattern (a joint's columns coupled with their
    ancestors' by a Jacobian-like sum), equality rows and inequality rows of which some cut
    through the equality-constrained optimum."""
    n = model.model.nv
    parents = column_parents(model.model)
    H = np.diag(rng.uniform(0.5, 2.0, n))
    for leaf in range(n):  # a task on each column's chain: its J^T J stays on the tree
        chain, k = [], leaf
        while k >= 0:
            chain.append(k)
            k = parents[k]
        J = np.zeros((3, n))
        J[:, chain] = rng.standard_normal((3, len(chain)))
        H += J.T @ J
    p = QpBuffer(n, tree).views(m_in, m_eq)
    p.H[:], p.c[:] = H, rng.standard_normal(n)
    p.A[:], p.b[:] = rng.standard_normal((m_eq, n)), 0.1 * rng.standard_normal(m_eq)
    p.G[:] = rng.standard_normal((m_in, n))
    p.h[:] = rng.uniform(-0.5, 2.0, m_in)
    return p


def _solved(p: QpProblem, native: Any) -> tuple[np.ndarray, bool]:
    solved = least_distance_daqp(daqp, 1000, p.H, p.c, p.G if len(p.h) else None,
                                 p.h if len(p.h) else None, p.A if len(p.b) else None,
                                 p.b if len(p.b) else None, None, None, native=native)
    assert solved is not None
    return solved[0].copy(), solved[1]


@pytest.mark.parametrize(("m_in", "m_eq"), [(12, 6), (13, 3), (5, 0), (0, 4)])
@pytest.mark.parametrize("seed", range(5))
def test_the_step_and_its_binding_rows_are_lapacks_and_daqps(human, tree, seed: int, m_in: int,
                                                            m_eq: int) -> None:
    p = _problem(np.random.default_rng(seed), human, tree, m_in, m_eq)
    assert p.packed is not None
    assert tree.least_distance_rows(p.packed, m_in, m_eq) is not None  # the kernel's form
    x, binding = _solved(p, (tree, p.packed))
    dense, dense_binding = _solved(p, None)
    given, given_binding = backends.daqp_as_given(
        daqp, 1000, p.H, p.c, p.G if m_in else None, p.h if m_in else None,
        p.A if m_eq else None, p.b if m_eq else None, None, None)
    assert given is not None
    assert binding == dense_binding == given_binding
    scale = max(1.0, float(np.abs(dense).max()))
    np.testing.assert_allclose(x, dense, rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(x, given, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(p.A @ x, p.b, rtol=0, atol=1e-9)  # the planted rows hold
    assert np.all(p.G @ x <= p.h + 1e-9)


def test_an_objective_off_the_tree_goes_to_lapack(human, tree) -> None:
    p = _problem(np.random.default_rng(3), human, tree, 12, 6)
    assert p.packed is not None
    chains = ancestors(column_parents(human.model))
    k = len(chains) - 1
    a = next(a for a in range(k) if a not in chains[k])  # another limb's column
    p.H[k, a] = p.H[a, k] = 1e-3
    assert tree.least_distance_rows(p.packed, 12, 6) is None
    x, binding = _solved(p, (tree, p.packed))  # LAPACK's factor: the very numbers
    dense, dense_binding = _solved(p, None)
    assert np.array_equal(x, dense) and binding == dense_binding


def test_the_solver_gives_the_lapack_factors_poses(human, tree, monkeypatch) -> None:
    """The 17-sensor simulated walk with contacts: every DAQP step the solver hands the tree
    factor is LAPACK's to rounding, with the same binding rows, and the poses agree."""
    truth = generate_gait(human, GaitParameters(duration=3.0, stand=1.0), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    used, differences = [0], [0.0]
    original = least_distance.least_distance_daqp

    def compared(module: Any, iterations: int, *problem: Any, native: Any = None) -> Any:
        solved = original(module, iterations, *problem, native=native)
        if native is not None:
            dense = original(module, iterations, *problem)
            assert (solved is None) == (dense is None)
            if solved is not None and dense is not None:
                used[0] += 1
                assert solved[1] == dense[1]
                differences[0] = max(differences[0], float(np.abs(solved[0] - dense[0]).max()))
        return solved

    monkeypatch.setattr(backends, "least_distance_daqp", compared)
    poses = Solver(human, backend="daqp", contacts=True).solve(frames).q
    assert used[0] >= 10, used[0]  # 19: the steps after a binding one
    assert differences[0] < 1e-11, differences[0]
    monkeypatch.setattr(backends, "least_distance_daqp", original)
    solver = Solver(human, backend="daqp", contacts=True)
    assert solver.compiled is not None
    solver.compiled.buffer.tree = None  # no native kernel at all: LAPACK throughout
    assert np.abs(poses - solver.solve(frames).q).max() < 1e-9
