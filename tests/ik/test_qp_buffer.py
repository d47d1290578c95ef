"""The preallocated QP buffer: the same problem as ``assemble_qp``, one finite check."""

from __future__ import annotations

import numpy as np
import pytest

from ikfusion.errors import SolverError
from ikfusion.ik.limits.base import Equality, Inequality
from ikfusion.ik.qp import QpBuffer, assemble_qp, solve_qp
from ikfusion.ik.settings import SolverSettings

NV = 12


def _blocks(rng: np.random.Generator, sizes_in: list[int], sizes_eq: list[int]
            ) -> tuple[np.ndarray, np.ndarray, list[Inequality], list[Equality]]:
    M = rng.standard_normal((NV, NV))
    H = M @ M.T + 0.1 * np.eye(NV)
    c = rng.standard_normal(NV)
    ineq = [Inequality(rng.standard_normal((m, NV)), rng.uniform(0.0, 1.0, m))
            for m in sizes_in]
    eq = [Equality(rng.standard_normal((m, NV)), 0.1 * rng.standard_normal(m))
          for m in sizes_eq]
    return H, c, ineq, eq


@pytest.mark.parametrize("seed", range(3))
def test_the_buffer_assembles_and_solves_exactly_as_assemble_qp(seed: int) -> None:
    rng = np.random.default_rng(seed)
    buffer = QpBuffer(NV)
    settings = SolverSettings.load().qp
    box = (np.full(NV, -0.3), np.full(NV, 0.3))
    # growing, shrinking and empty blocks, one buffer for all of them
    # (the first size again after the buffer grew: its views are made anew)
    for sizes_in, sizes_eq in (([3, 0, 5], [2]), ([20, 7], [6, 3]), ([], []), ([1], [0, 4]),
                               ([3, 0, 5], [2])):
        H, c, ineq, eq = _blocks(rng, sizes_in, sizes_eq)
        H_before = H.copy()
        packed = buffer.assemble(H, c, ineq, eq, box, 1e-4)
        np.testing.assert_array_equal(H, H_before)  # H is copied, not changed
        expected = assemble_qp(H.copy(), c, ineq, eq, box, 1e-4)
        for name in ("H", "c", "G", "h", "A", "b"):
            got, want = getattr(packed, name), getattr(expected, name)
            assert got.shape == want.shape, name
            np.testing.assert_array_equal(got, want, err_msg=name)
        x_packed = solve_qp(packed, "daqp", settings)
        x_expected = solve_qp(expected, "daqp", settings)
        np.testing.assert_array_equal(x_packed.dq, x_expected.dq)
        assert x_packed.relaxed == x_expected.relaxed


@pytest.mark.parametrize("where", ["G", "c", "b"])
def test_a_packed_problem_holding_nan_is_refused_by_name(where: str) -> None:
    H, c, ineq, eq = _blocks(np.random.default_rng(7), [4], [2])
    {"G": ineq[0].G, "c": c, "b": eq[0].b}[where][0] = np.nan
    problem = QpBuffer(NV).assemble(H, c, ineq, eq, None, 1e-4)
    with pytest.raises(SolverError, match=f"\\b{where}\\b"):
        solve_qp(problem, "daqp", SolverSettings.load().qp)


def test_views_are_consecutive_blocks_of_one_array() -> None:
    buffer = QpBuffer(NV)
    problem = buffer.views(3, 2)
    assert problem.packed is not None and problem.packed.size == NV * NV + NV + 5 * (NV + 1)
    blocks = [problem.H, problem.c, problem.G, problem.h, problem.A, problem.b]
    assert [b.shape for b in blocks] == [(NV, NV), (NV,), (3, NV), (3,), (2, NV), (2,)]
    problem.packed[:] = np.arange(problem.packed.size)
    assert np.concatenate([b.reshape(-1) for b in blocks]).tolist() == \
        problem.packed.tolist()


def test_rows_added_by_the_active_set_are_checked_not_the_stale_packing() -> None:
    """A packed problem whose left-out range row the step crosses: once the active set stacks
    that row into a new G, the packed array no longer holds the problem's rows (its one-sum
    finite check would read the old ones)."""
    from ikfusion.ik.active_set import LimitRows, solve_with_active_set
    from ikfusion.ik.limits.joint_range import LinearisedRanges

    H = np.eye(NV)
    c = -np.ones(NV)  # unconstrained step: dq = 1 in every column
    ranges = LinearisedRanges(np.eye(NV)[:2], np.array([[0.5, 2.0], [2.0, 2.0]]))
    up, down = np.zeros(2, dtype=bool), np.zeros(2, dtype=bool)
    floor = Inequality(np.zeros((0, NV)), np.zeros(0))
    problem = QpBuffer(NV).assemble(H, c, [], [], None, 0.0)
    rows = LimitRows(ranges, up, down, floor, None)
    solution = solve_with_active_set(problem, rows, "daqp", SolverSettings.load().qp, 1e-6, 2)
    assert rows.up.tolist() == [True, False]  # the crossed row was added
    assert solution.dq[0] == pytest.approx(0.5)
    assert problem.packed is None or np.shares_memory(problem.G, problem.packed)
