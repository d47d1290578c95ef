"""The common step of the lazy active set in one native call (TreeClosedForm.step through
ikfusion.ik.active_set), and the first test of a DAQP step (TreeClosedForm.passes_none), against
the Python loop they short-cut: the same steps bit for bit, the same rows added, on random
problems (rows crossed, bounds passed, rates exactly at their limits) and on the solver's
walk."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import ikfusion.ik.active_set as active_set
from ikfusion.ik import Solver
from ikfusion.ik.active_set import LimitRows, solve_with_active_set
from ikfusion.ik.equality_qp import ClosedFormHint
from ikfusion.ik.limits.base import Inequality
from ikfusion.ik.limits.joint_range import LinearisedRanges
from ikfusion.ik.qp import QpBuffer, QpProblem, QpSettings
from ikfusion.ik.tree_solve import (
    CROSSES,
    GOES_ON,
    NOT_TREE,
    SOLVED,
    TreeClosedForm,
)
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames

SETTINGS = QpSettings(max_iterations=1000, slack_weight=1e6, relaxed_slack_scale=1e-3,
                      osqp_tolerance=1e-9, osqp_max_iterations=10000)
TOLERANCE = 1e-4


@pytest.fixture(scope="module")
def model() -> HumanModel:
    return HumanModel.default()


def _python_loop(*args: object) -> object:
    return None, None


def _python_only(m: pytest.MonkeyPatch) -> None:
    """Neither the native common step nor the native first test of a DAQP step."""
    m.setattr(active_set, "_native_step", _python_loop)
    m.setattr(active_set, "_surely_within", lambda *args: False)


def _step(rng: np.random.Generator, model: HumanModel, tree: TreeClosedForm
          ) -> tuple[QpProblem, LimitRows]:
    """A step's QP on a diagonal H (on any tree), two contact rows, a floor row, and range rows
    (three a joint, as the joints' rates) some near their limits, with velocity bounds."""
    n = model.model.nv
    joints = list(model.ball_joints.values())
    G = np.zeros((3 * len(joints), n))
    for j, joint in enumerate(joints):
        G[3 * j:3 * j + 3, joint.idx_v:joint.idx_v + 3] = rng.standard_normal((3, 3))
    rooms = rng.uniform(-0.01, 0.3, (2, len(G)))
    up, down = rooms < 0.05
    m_in = int(up.sum() + down.sum()) + 1
    p = QpBuffer(n, tree).views(m_in, 2)
    p.H[:] = np.diag(rng.uniform(1.0, 2.0, n))
    size = rng.choice([1e-3, 0.1])  # of the step: mostly within its limits, or not
    p.c[:] = rng.standard_normal(n) * size
    p.A[:], p.b[:] = rng.standard_normal((2, n)), rng.standard_normal(2) * size
    p.G[:-1] = np.vstack([G[up], -G[down]])
    p.h[:-1] = np.concatenate([rooms[0][up], rooms[1][down]]) + 1.0  # rarely binding
    p.G[-1], p.h[-1] = rng.standard_normal(n), 10.0
    floor = Inequality(p.G[-1:].copy(), p.h[-1:].copy())
    span = rng.uniform(0.05, 1.0)
    bounds = (np.full(n, -span), np.full(n, span))
    return p, LimitRows(LinearisedRanges(G, rooms), up, down, floor, bounds)


def _both(p: QpProblem, rows: LimitRows, monkeypatch: pytest.MonkeyPatch
          ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, bool]]:
    """The step and the rows kept by the native common step and by the Python loop."""
    made = []
    for native in (True, False):
        problem = copy.deepcopy(p, {id(p.tree): p.tree})  # the kernel shared, not copied
        limit_rows = copy.deepcopy(rows)
        with monkeypatch.context() as m:
            if not native:
                _python_only(m)
            solution = solve_with_active_set(problem, limit_rows, "daqp", SETTINGS, TOLERANCE,
                                             2, ClosedFormHint())
        made.append((solution.dq, limit_rows.up, limit_rows.down, solution.relaxed))
    return made


def test_random_steps_are_the_python_loops_bit_for_bit(tree, model, monkeypatch) -> None:
    rng = np.random.default_rng(7)
    answers = set()
    for trial in range(80):
        p, rows = _step(rng, model, tree)
        assert p.packed is not None
        if trial % 4 == 1:  # the floor row cuts through the closed form's step: DAQP's
            tree.solve(p.packed, len(p.h), len(p.b))
            p.h[-1] = p.G[-1] @ tree.x - 1e-3
        elif trial % 4 == 2:  # H off the tree's pattern: LAPACK's closed form
            k, a = divmod(int(tree._off[trial % len(tree._off)]), len(p.c))
            p.H[k, a] = p.H[a, k] = 1e-3
        answers.add(tree.step(p.packed, len(p.h), len(p.b), rows.ranges, rows.up, rows.down,
                              rows.bounds, TOLERANCE))
        native, python = _both(p, rows, monkeypatch)
        for a, b in zip(native, python):
            np.testing.assert_array_equal(a, b)
    assert {SOLVED, GOES_ON, CROSSES, NOT_TREE} <= answers  # every way on was tried


def test_a_rate_at_its_limit_goes_to_the_python_loop(tree, model, monkeypatch) -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        p, rows = _step(rng, model, tree)
        assert p.packed is not None
        rows.bounds = None
        tree.solve(p.packed, len(p.h), len(p.b))
        rate = rows.ranges.G @ tree.x
        left_out = np.flatnonzero(~rows.up & (rate != 0.0))
        if not len(left_out):
            continue
        i = left_out[0]
        rows.ranges.rooms[0, i] = rate[i] - TOLERANCE  # on the limit, to rounding
        assert tree.step(p.packed, len(p.h), len(p.b), rows.ranges, rows.up, rows.down, None,
                         TOLERANCE) == GOES_ON
        native, python = _both(p, rows, monkeypatch)
        for a, b in zip(native, python):
            np.testing.assert_array_equal(a, b)


def test_a_bound_passed_or_a_row_crossed_is_not_the_common_step(tree, model) -> None:
    p, rows = _step(np.random.default_rng(11), model, tree)
    assert p.packed is not None
    rows.ranges.rooms[:] = np.inf
    rows.up[:], rows.down[:] = False, False
    args = (p.packed, len(p.h), len(p.b), rows.ranges, rows.up, rows.down)
    assert tree.step(*args, None, TOLERANCE) == SOLVED
    x = tree.x.copy()
    k = int(np.argmax(np.abs(x)))
    wide = (np.full(len(x), -np.inf), np.full(len(x), np.inf))
    assert tree.step(*args, wide, TOLERANCE) == SOLVED
    tight = (wide[0].copy(), wide[1].copy())
    (tight[1] if x[k] > 0 else tight[0])[k] = x[k] - np.sign(x[k]) * 2 * TOLERANCE
    assert tree.step(*args, tight, TOLERANCE) == GOES_ON
    i = int(np.argmax(np.abs(rows.ranges.G @ x)))
    rate = float(rows.ranges.G[i] @ x)
    rows.ranges.rooms[0 if rate > 0 else 1, i] = abs(rate) - 2 * TOLERANCE
    assert tree.step(*args, None, TOLERANCE) == GOES_ON
    (rows.up if rate > 0 else rows.down)[i] = True  # in the QP: not tested again
    assert tree.step(*args, None, TOLERANCE) == SOLVED


def test_the_solver_gives_the_python_loops_poses(tree, model, monkeypatch) -> None:
    truth = generate_gait(model, GaitParameters(duration=3.0, stand=1.0), rate=60.0)
    frames = orientation_frames(model, truth.q, truth.time, SENSOR_SEGMENTS)
    poses = []
    for native in (True, False):
        with monkeypatch.context() as m:
            if not native:
                _python_only(m)
            poses.append(Solver(model, backend="daqp").solve(frames).q)
    np.testing.assert_array_equal(poses[0], poses[1])


def test_the_native_test_of_a_daqp_step_says_none_passed_only_where_the_loop_does(
        tree, model) -> None:
    rng = np.random.default_rng(5)
    seen = set()
    for trial in range(300):
        _, rows = _step(rng, model, tree)
        x = rng.standard_normal(tree.n) * rng.choice([1e-3, 1e-2, 0.1])
        rate = rows.ranges.G @ x
        at_limit = trial % 3 == 0
        if at_limit:  # a left-out rate on its limit, to rounding: the loop must decide
            i = int(rng.integers(len(rate)))
            rows.ranges.rooms[0, i] = rate[i] - TOLERANCE
            rows.up[i] = False
        bounds = rows.bounds if trial % 2 else None
        native = tree.passes_none(x, rows.ranges, rows.up, rows.down, bounds, TOLERANCE)
        up, down = rows.ranges.crossed(x, TOLERANCE)
        passed = bool(np.any(up & ~rows.up) or np.any(down & ~rows.down)) or (
            bounds is not None and bool(np.any(x < bounds[0] - TOLERANCE)
                                        or np.any(x > bounds[1] + TOLERANCE)))
        assert not (native and passed)
        assert not (native and at_limit)
        seen.add((native, passed))
    assert seen == {(True, False), (False, False), (False, True)}
