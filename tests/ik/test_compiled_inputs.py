"""Inputs written into their slots only when they changed give the numbers of every input set.

An input is left in its slot only while it is the same read-only object; any array that can
be written (in place, through a view, or after its flag is turned back) is written again.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from test_bound_function import small_function

from ikfusion.ik import Solver
from ikfusion.ik.bound_function import BoundFunction, column_major
from ikfusion.ik.compiled import MIRRORED
from ikfusion.ik.compiled_inputs import SlotInputs
from ikfusion.ik.step_ranges import RateRows
from ikfusion.model import HumanModel
from ikfusion.rotations import random_rotations


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def test_kept_inputs_follow_every_change(rng) -> None:
    """In-place edits, views of a writeable array and re-enabled flags are all seen.

    Each call is compared with CasADi's own evaluation of the same numbers.
    """
    f = small_function()
    inputs = SlotInputs(BoundFunction(f), varying=(0,), rotations=(1,), triples=())
    R = _read_only(random_rotations(2, rng))
    s = np.array([0.5])
    base = random_rotations(2, rng)
    view = _read_only(base[:])  # read-only, its memory writeable elsewhere

    def check(R_now: np.ndarray, s_now: np.ndarray) -> None:
        x = rng.normal(size=3)
        call = inputs.set((x, R_now, s_now))
        expected = [np.asarray(v) for v in f(x, column_major(R_now), s_now)]
        assert np.array_equal(call.output(0)[:, 0], expected[0][:, 0])
        assert np.array_equal(call.output(1), expected[1])

    check(R, s)
    check(R, s)  # kept: the same read-only object
    s[0] = -2.0  # a writeable input edited in place
    check(R, s)
    R.setflags(write=True)  # the owner made writeable again and edited
    R[:] = random_rotations(2, rng)
    check(R, s)
    check(view, s)
    check(view, s)
    base[:] = random_rotations(2, rng)  # the view's numbers change through its base
    check(view, s)
    R2 = _read_only(random_rotations(2, rng))  # another object
    check(R2, s)
    check(R, s)


def test_compiled_step_equals_every_input_packed(human: HumanModel, rng) -> None:
    """The solver's step function through its slots: the outputs of all inputs packed, bit for
    bit, over calls that change some inputs, keep others, edit one in place and switch sets."""
    solver = Solver(human)
    assert solver.compiled is not None, "the compiled step function is needed here"
    kin, geometry = solver.compiled.kinematics, solver.compiled.geometry
    limits = solver.tasks.joint_range
    reference = BoundFunction(kin.function, MIRRORED)  # H: its lower triangle, mirrored
    model = human.model
    k, j = len(kin.segment_frames), len(limits.lower)
    kept = [_read_only(rng.uniform(0.0, 2.0, 3 * k)), _read_only(rng.uniform(0.0, 2.0, 3 * j))]
    R_reference = _read_only(random_rotations(j, rng))
    w_persist = rng.uniform(0.0, 3.0, model.nv)  # writeable: edited in place below
    w_persist[kin.persistence_excluded] = 0.0
    no_chain = np.zeros(3 * len(solver.tasks.even_chain.pairs))
    for n in range(8):
        q = pin.integrate(model, human.neutral(), rng.normal(0.0, 0.5, model.nv))
        targets = random_rotations(k, rng)
        if n == 4:  # new weights (a sensor dropped out)
            kept = [_read_only(rng.uniform(0.0, 2.0, 3 * k)), kept[1]]
        if n == 5:
            w_persist[6:] *= 0.5
        persist = (w_persist, q + 0.01) if n % 3 else None
        step = kin.evaluate(q, targets, geometry, *kept, R_reference,
                            (limits.lower, limits.upper), None, None, persist)
        w, q_persist = persist if persist is not None else (np.zeros(model.nv), q)
        reference.evaluate(q, np.swapaxes(targets, 1, 2), geometry, *kept,
                           np.swapaxes(R_reference, 1, 2), limits.lower, limits.upper,
                           no_chain, no_chain, q, w, q_persist)
        for i in range(kin.function.n_out()):
            assert step.output(i).tobytes() == reference.output(i).tobytes(), (n, i)


def test_still_angles_found_past_their_witnesses(rng) -> None:
    """The mask of all-zero rate rows equals a search of every row, call after call, while
    rows turn zero (gimbal lock) and back, and some rates are zero without the row being so."""
    rows = rng.permutation(30).reshape(10, 3)
    rates = RateRows(rows)
    for _ in range(40):
        nonzeros = rng.normal(size=30)
        nonzeros[rng.random(30) < 0.4] = 0.0  # single rates at zero
        nonzeros[rows[rng.random(10) < 0.2]] = 0.0  # whole rows at zero
        expected = ~np.any(nonzeros[rows] != 0.0, axis=1)
        np.testing.assert_array_equal(rates.still(nonzeros), expected)


def test_inputs_of_other_forms_and_a_kept_input_not_an_array(rng) -> None:
    """Varying inputs given as lists or nested lists, and a kept input that is a list (written
    at every call, its numbers changed between calls): CasADi's numbers of the same inputs."""
    f = small_function()
    inputs = SlotInputs(BoundFunction(f), varying=(0, 1), rotations=(1,), triples=())
    s = [0.5]
    for n in range(4):
        x = rng.normal(size=3)
        R = random_rotations(2, rng)
        given_x = list(x) if n % 2 else x
        given_R = R.tolist() if n == 2 else R
        s[0] = float(n) - 1.5  # the same list, other numbers
        call = inputs.set((given_x, given_R, s))
        expected = [np.asarray(v) for v in f(x, column_major(R), s[0])]
        assert np.array_equal(call.output(0)[:, 0], expected[0][:, 0]), n
        assert np.array_equal(call.output(1), expected[1]), n
