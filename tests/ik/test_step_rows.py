"""The native step writer (ikfusion.ik.step_rows) builds the NumPy path's QP (issue #20).

Every step of a walk with contacts (simulated gait, the real Xsens walk when ../shared is
there) and of random poses near many limits, with the site targets', the root's and the swing
feet's position rows, is built twice: by the kernel and by the NumPy path it replaces. The QPs
agree to round-off (only the position rows' summation order differs), the limit masks exactly.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from real_walk import solve_real_walk_natively

from ikfusion.ik import Frame, Solver
from ikfusion.ik import frame_problem as fp
from ikfusion.ik import solver as solver_module
from ikfusion.ik.limits import ContactConstraint, FloorLimit
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.rotations import random_rotations
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames

TIGHT = 1e-12  # relative to the largest entry of the array compared
_NAMES = ("H", "c", "G", "h", "A", "b")


def _bounds_bytes(problem: fp.FrameProblem) -> bytes | None:
    """The velocity bounds of ``problem`` as their bytes (None without bounds)."""
    bounds = problem.rows.bounds
    return None if bounds is None else bounds[0].tobytes() + bounds[1].tobytes()


def _compare(native: fp.FrameProblem, numpy: dict[str, np.ndarray], masks, rooms,
             floor, bounds: bytes | None) -> bool:
    """Assert the kernel's problem is the NumPy one's (its velocity bounds bit for bit);
    whether bit for bit."""
    assert _bounds_bytes(native) == bounds
    same = True
    for name in _NAMES:
        ours, theirs = getattr(native.qp, name), numpy[name]
        assert ours.shape == theirs.shape, name
        scale = max(np.abs(theirs).max(initial=0.0), 1e-300)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=TIGHT * scale, err_msg=name)
        same &= np.array_equal(ours, theirs)
    np.testing.assert_array_equal(native.rows.up, masks[0])
    np.testing.assert_array_equal(native.rows.down, masks[1])
    np.testing.assert_array_equal(native.rows.ranges.rooms, rooms)
    for ours, theirs in zip(native.rows.floor, floor):
        np.testing.assert_array_equal(ours, theirs)
    return same


class _BothPaths:
    """``build_frame_problem`` that builds each step by NumPy and by the kernel and compares."""

    def __init__(self) -> None:
        self.steps = self.exact = self.root = self.swing = self.contact = self.sites = 0
        self.bounded = 0

    def __call__(self, conf, tasks, active, row_weights, compiled, lm):
        if compiled is None or compiled.rows is None:
            return fp.build_frame_problem(conf, tasks, active, row_weights, compiled, lm)
        plain = fp.build_frame_problem(conf, tasks, active, row_weights,
                                       dataclasses.replace(compiled, rows=None), lm)
        numpy = {n: getattr(plain.qp, n).copy() for n in _NAMES}
        masks = plain.rows.up.copy(), plain.rows.down.copy()
        rooms = plain.rows.ranges.rooms.copy()
        floor = [a.copy() for a in plain.rows.floor]
        bounds = _bounds_bytes(plain)
        native = fp.build_frame_problem(conf, tasks, active, row_weights, compiled, lm)
        self.last = (conf, tasks, active, row_weights, compiled, lm)
        self.steps += 1
        self.exact += _compare(native, numpy, masks, rooms, floor, bounds)
        self.bounded += bounds is not None
        self.root += tasks.root in active
        self.swing += tasks.swing in active
        self.contact += len(numpy["b"]) > 0
        self.sites += tasks.position.has_targets()
        return native


@pytest.fixture
def both(monkeypatch: pytest.MonkeyPatch) -> _BothPaths:
    made = _BothPaths()
    monkeypatch.setattr(solver_module, "build_frame_problem", made)
    return made


def _native_solver(human: HumanModel, contacts: bool) -> Solver:
    solver = Solver(human, contacts=contacts)
    if solver.compiled is None or solver.compiled.rows is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    return solver


def test_every_step_of_a_simulated_walk(human: HumanModel, both: _BothPaths) -> None:
    truth = generate_gait(human, GaitParameters(duration=3.0, stand=0.5), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    _native_solver(human, contacts=True).solve(frames)
    assert both.steps >= len(frames) and both.contact > len(frames) // 2
    assert both.root > 0 and both.sites > 0  # the position rows' sums too
    assert both.bounded >= len(frames) - 1  # the velocity bounds too


def test_the_real_walk(both: _BothPaths, tmp_path: Path) -> None:
    solve_real_walk_natively(tmp_path / "out")
    assert both.steps >= 2505 and both.contact > 1000 and both.root > 1000


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_poses_with_site_root_swing_and_contact_rows(human: HumanModel, seed: int,
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    rng = np.random.default_rng(seed)
    solver = _native_solver(human, contacts=True)
    q = human.neutral()
    for joint in human.ball_joints.values():  # turned far: many angles near or past a limit
        q[joint.idx_q:joint.idx_q + 4] = pin.Quaternion(random_rotations(1, rng)[0]).coeffs()
    frame = Frame(0.0, dict(zip(SENSOR_SEGMENTS, random_rotations(len(SENSOR_SEGMENTS), rng))))
    solver.step(frame)  # a previous frame: damping, velocity bounds
    tasks, s = solver.tasks, solver.settings
    targets = solver.targets.load(frame, None)
    k = len(tasks.contact_rows)
    planted = rng.random(k) < 0.5
    # one fully held point a segment (the others of its segment rising, held horizontally):
    # the kernel's case, the points held along the world axes
    rising = np.zeros(k, dtype=bool)
    first: set[str] = set()
    for i in np.flatnonzero(planted):
        segment = tasks.contact.segments[i]
        rising[i] = segment in first
        first.add(segment)
    tasks.contact.set_anchors(planted, rng.normal(scale=0.3, size=(k, 3)), rising)
    assert tasks.contact.world_rows() is not None
    tasks.floor.enabled = rng.random(k) < 0.7
    tasks.root.set_target(tuple(rng.normal(size=3)), 30.0)
    tasks.swing.set_targets(rng.normal(size=(k, 3)), np.where(planted, 0.0, rng.random(k)))
    sites = len(tasks.position.frame_ids)  # site targets on some of them
    tasks.position.set_targets(rng.normal(size=(sites, 3)),
                               np.where(rng.random(sites) < 0.3, 1e4 * rng.random(sites), 0.0))
    active = [*solver._base_tasks(frame), tasks.root, tasks.swing]
    conf = solver._configuration
    conf.update(q)
    compiled = solver.compiled
    assert compiled is not None
    plain = fp.build_frame_problem(conf, tasks, active, targets.row_weights,
                                   dataclasses.replace(compiled, rows=None),
                                   s.levenberg_marquardt)
    numpy = {n: getattr(plain.qp, n).copy() for n in _NAMES}
    masks = plain.rows.up.copy(), plain.rows.down.copy()
    rooms, floor = plain.rows.ranges.rooms.copy(), [a.copy() for a in plain.rows.floor]
    bounds = _bounds_bytes(plain)
    written: list[object] = []
    write = compiled.rows.write

    def recorded_write(*args, **kwargs):
        written.append(write(*args, **kwargs))
        return written[-1]
    monkeypatch.setattr(compiled.rows, "write", recorded_write)
    native = fp.build_frame_problem(conf, tasks, active, targets.row_weights, compiled,
                                    s.levenberg_marquardt)
    assert len(written) == 1 and written[0] is not None  # the kernel wrote this QP
    assert masks[0].sum() + masks[1].sum() >= 10 and len(numpy["b"]) > 0
    _compare(native, numpy, masks, rooms, floor, bounds)
    assert native.qp.packed is not None and np.shares_memory(native.qp.G, native.qp.packed)


def test_velocity_bounds_at_special_spans(human: HumanModel, both: _BothPaths, rng) -> None:
    """The kernel's velocity bounds (and never NumPy's) are NumPy's bit for bit at zero,
    signed-zero, infinite, NaN, tiny and huge spans, after a simulated walk's steps."""
    truth = generate_gait(human, GaitParameters(duration=1.0, stand=0.5), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    _native_solver(human, contacts=True).solve(frames)
    conf, tasks, active, row_weights, compiled, lm = both.last
    velocity = tasks.velocity
    special = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300, 1e300, 5e-324]
    nv = len(velocity.max_velocity)
    velocity.max_velocity = np.resize(special + list(rng.uniform(0, 3, nv)), nv)
    # a previous frame 10 ms before, the damping's reference too (the kernel's case)
    q_previous = pin.integrate(conf.model, conf.q, rng.normal(0.0, 0.05, nv))
    q_previous[:3] = conf.q[:3]  # (a root translation not moved: some moves exactly zero)
    tasks.damping.set_reference(q_previous)
    velocity.set_previous(q_previous, 0.01)
    plain = fp.build_frame_problem(conf, tasks, active, row_weights,
                                   dataclasses.replace(compiled, rows=None), lm)
    expected = _bounds_bytes(plain)
    assert expected is not None
    for a in plain.rows.bounds:
        a.fill(np.nan)

    def not_numpy(*args):
        raise AssertionError("the NumPy bounds were computed: expected the kernel's")

    velocity.bounds = not_numpy
    try:
        native = fp.build_frame_problem(conf, tasks, active, row_weights, compiled, lm)
    finally:
        del velocity.bounds
    assert _bounds_bytes(native) == expected


def test_without_a_compiler_the_numpy_path_builds(human: HumanModel,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    from ikfusion.ik import step_rows
    monkeypatch.setenv("IKFUSION_NO_COMPILE", "1")
    assert step_rows.step_rows(fp.QpBuffer(human.model.nv), np.zeros((3, 3), dtype=int),
                               np.zeros(0, dtype=int), 0.1) is None


def test_contact_rows_and_anchors_are_replaced_never_written_in_place() -> None:
    """What the writer's skipped copies rely on: new contacts, new arrays; the old ones keep
    their numbers (so the same array again holds the same numbers)."""
    contact = ContactConstraint([1, 2, 3], ["a", "b", "c"])
    contact.set_anchors([True, False, True], [[0.1, 0.2, 0.0], [0, 0, 0], [0.4, 0.5, 0.0]])
    anchors, rows = contact.anchors, contact.world_rows()
    kept_anchors, kept_rows = anchors.copy(), np.array(rows)
    contact.set_anchors([True, True, False], [[0.3, 0.2, 0.0], [0.7, 0.1, 0.0], [0, 0, 0]],
                        [False, True, False])
    assert contact.anchors is not anchors and contact.world_rows() is not rows
    np.testing.assert_array_equal(anchors, kept_anchors)
    np.testing.assert_array_equal(rows, kept_rows)
    np.testing.assert_array_equal(contact.world_rows(), [0, 1, 2, 3, 4])
    floor = FloorLimit([1, 2, 3])
    every = floor.z_rows()
    floor.enabled = np.array([False, True, True])
    assert floor.z_rows() is not every
    np.testing.assert_array_equal(every, [2, 5, 8])
    np.testing.assert_array_equal(floor.z_rows(), [5, 8])
