"""BoundFunction: CasADi functions evaluated on preallocated buffers give CasADi's own numbers."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from ikfusion.ik.bound_function import BoundFunction, column_major
from ikfusion.rotations import random_rotations


def small_function() -> ca.Function:
    """Inputs of three sizes (a vector, stacked rotations, a scalar); a dense and a sparse
    output."""
    x = ca.SX.sym("x", 3)
    R = ca.SX.sym("R", 18)  # two rotations, column-major
    s = ca.SX.sym("s", 1)
    first = ca.reshape(R[:9], 3, 3)
    second = ca.reshape(R[9:], 3, 3)
    sparse = ca.SX(3, 4)
    sparse[0, 1] = s * x[0]
    sparse[2, 3] = ca.sin(x[2])
    return ca.Function("f", [x, R, s], [first @ x + s * (second.T @ x), sparse])


def test_inputs_copied_at_once_give_casadis_numbers() -> None:
    """Every input set in one packed copy (rotations as a transposed view, no column-major
    copy) evaluates to what CasADi computes from the same numbers."""
    rng = np.random.default_rng(4)
    f = small_function()
    call = BoundFunction(f)
    for _ in range(3):
        x, R, s = rng.normal(size=3), random_rotations(2, rng), rng.normal(size=1)
        expected = [np.asarray(v) for v in f(x, column_major(R), s)]
        call.evaluate(x, np.swapaxes(R, 1, 2), s)
        assert np.array_equal(call.output(0)[:, 0], expected[0][:, 0])
        assert np.array_equal(call.output(1), expected[1])
        # the same through the column-major copy and the per-input path (fewer inputs)
        outputs = call(x, column_major(R), s)
        assert np.array_equal(outputs[0], expected[0])
        call.evaluate(x + 1.0)  # R and s keep their values
        assert np.array_equal(call.output(0)[:, 0],
                              np.asarray(f(x + 1.0, column_major(R), s)[0])[:, 0])


def test_an_input_of_the_wrong_size_is_refused_not_shifted() -> None:
    """Sizes that add up to the packed total but are not the inputs' own (a 4-vector where 3
    go, a 17-vector where 18 go) are an error, never numbers moved into the next input."""
    call = BoundFunction(small_function())
    with pytest.raises(ValueError):
        call.evaluate(np.zeros(4), np.zeros(17), np.zeros(1))
    with pytest.raises(ValueError):
        call.evaluate(np.zeros(3), np.zeros(18), np.zeros(2))


def test_an_output_written_into_an_array_is_the_dense_output() -> None:
    """``output_into`` writes ``output``'s numbers (the sparse output's structural zeros too,
    over whatever the array held) into a contiguous array and into a strided view."""
    rng = np.random.default_rng(5)
    call = BoundFunction(small_function())
    call.evaluate(rng.normal(size=3), np.swapaxes(random_rotations(2, rng), 1, 2),
                  rng.normal(size=1))
    for i in (0, 1):
        expected = call.output(i).copy()
        out = np.full(expected.shape, np.nan)
        call.output_into(i, out)
        assert np.array_equal(out, expected)
        strided = np.full((expected.shape[0], 2 * expected.shape[1]), np.nan)[:, ::2]
        call.output_into(i, strided)
        assert np.array_equal(strided, expected)


def test_adjacent_dense_vectors_read_as_one_array() -> None:
    """Two dense vector outputs of one size, one after the other, read as the rows of one
    array: the outputs themselves (a view); other outputs are refused."""
    x = ca.SX.sym("x", 3)
    sparse = ca.SX(3, 3)
    sparse[0, 1] = x[0]
    f = ca.Function("g", [x], [2.0 * x, x * x, ca.sum1(x), sparse])
    call = BoundFunction(f)
    x0 = np.array([1.0, -2.0, 0.5])
    call.evaluate(x0)
    both = call.vectors(0, 2)
    np.testing.assert_array_equal(both, [2.0 * x0, x0 * x0])
    call.evaluate(-x0)
    np.testing.assert_array_equal(both, [-2.0 * x0, x0 * x0])  # overwritten in place
    for first, count in [(1, 2), (2, 2)]:  # sizes that differ; a sparse output
        with pytest.raises(ValueError, match="dense vectors"):
            call.vectors(first, count)
