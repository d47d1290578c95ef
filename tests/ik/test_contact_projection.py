"""The native projection onto the contacts (ikfusion.ik.contact_projection) is the Python one.

Every projection of a simulated walk (and of the real Xsens walk when ../shared is there) and of
random poses with random anchors is done twice, by the kernel and by the Python loop it
replaces (the reference): the same answer (held, the QPs, the same number of steps) and the same
configuration to round-off. The kernel's integration is Pinocchio's to round-off.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from real_walk import solve_real_walk_natively

from ikfusion.ik import Frame, Solver
from ikfusion.ik import projection as projection_module
from ikfusion.ik import solver as solver_module
from ikfusion.ik.contact_projection import HELD, TO_QP, ball_joints, native_projection
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.native.build import usable_compiler
from ikfusion.native.kernel import kernel_source, loaded_kernel
from ikfusion.rotations import random_rotations
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames

TIGHT = 1e-12  # [m] or quaternion units: a configuration's round-off after a few steps
LOOSE = 1e-10  # the same after steps of up to 5 cm on random poses (worse conditioned)


class _BothPaths:
    """``project_on_contacts`` by the kernel and by the Python loop, compared."""

    def __init__(self) -> None:
        self.calls = self.native = self.steps = self.to_qp = self.crossed = 0
        self.in_place = 0  # held without a step: the configuration kept, its points read
        self.largest_difference = 0.0

    def __call__(self, conf, contact, floor, ranges, frames, tolerance, max_steps, backend,
                 qp, native=None):
        if native is None or native.conf is not conf or contact.world_rows() is None:
            return projection_module.project_on_contacts(
                conf, contact, floor, ranges, frames, tolerance, max_steps, backend, qp, native)
        q_start = conf.q.copy()
        relaxed = projection_module.project_on_contacts(
            conf, contact, floor, ranges, frames, tolerance, max_steps, backend, qp)
        reference = conf.q.copy()
        conf.update(q_start)
        answers: list[int] = []
        project = native.project
        native.project = lambda *args: answers.append(project(*args)) or answers[-1]
        try:
            ours = projection_module.project_on_contacts(
                conf, contact, floor, ranges, frames, tolerance, max_steps, backend, qp, native)
        finally:
            del native.project
        assert ours == relaxed
        if answers == [TO_QP]:  # the same QPs from the same start, a closed-form try skipped
            np.testing.assert_array_equal(conf.q, reference)  # only when it fails: bit for bit
            self.to_qp += 1
            self.crossed += native.plan.floor_crossed
        difference = float(np.abs(conf.q - reference).max())
        assert difference <= TIGHT, difference
        self.largest_difference = max(self.largest_difference, difference)
        self.in_place += answers == [HELD] and native.plan.steps == 0
        kept = conf.positions(frames).copy()  # read from the kernel's last call
        conf.update(conf.q.copy())
        np.testing.assert_array_equal(conf.positions(frames), kept)  # evaluated again
        self.calls += 1
        self.steps += native.plan.steps
        return ours


@pytest.fixture
def both(monkeypatch: pytest.MonkeyPatch) -> _BothPaths:
    made = _BothPaths()
    monkeypatch.setattr(solver_module, "project_on_contacts", made)
    return made


def _native_solver(human: HumanModel) -> Solver:
    solver = Solver(human, contacts=True)
    if solver._projection is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    return solver


def test_the_integration_is_pinocchios(human: HumanModel) -> None:
    if usable_compiler() is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    library = loaded_kernel(kernel_source(projection_module.__name__, "contact_projection.c"))
    assert library is not None
    model = human.model
    balls = ball_joints(model)
    assert balls is not None
    rng = np.random.default_rng(0)
    out = np.zeros(model.nq)
    pointer = ctypes.c_void_p
    for scale in (0.0, 1e-9, 1e-5, 1e-3, 0.1, 1.0, 3.0):  # both sides of the Taylor branches
        for _ in range(50):
            q = pin.integrate(model, pin.neutral(model), rng.normal(size=model.nv) * 2)
            q[:3] = rng.normal(size=3)
            dq = rng.normal(size=model.nv) * scale
            library.ik_integrate(ctypes.c_int(model.nq), ctypes.c_int(len(balls[0])),
                                 *(pointer(a.ctypes.data) for a in (*balls, q, dq, out)))
            np.testing.assert_allclose(out, pin.integrate(model, q, dq), rtol=0, atol=1e-15)


def test_every_projection_of_a_simulated_walk(human: HumanModel, both: _BothPaths) -> None:
    truth = generate_gait(human, GaitParameters(duration=3.0, stand=0.5), rate=60.0)
    frames = orientation_frames(human, truth.q, truth.time, SENSOR_SEGMENTS)
    _native_solver(human).solve(frames)
    assert both.calls >= len(frames) // 2 and both.steps > 0 and both.in_place > 0


def test_the_real_walk(both: _BothPaths, tmp_path: Path) -> None:
    solve_real_walk_natively(tmp_path / "out")
    assert both.calls >= 2000 and both.steps > 1000 and both.in_place > 1000
    assert both.to_qp > 100 and both.crossed > 0.9 * both.to_qp


@pytest.mark.parametrize("seed", range(4))
def test_random_poses_and_anchors(human: HumanModel, seed: int) -> None:
    """Anchors a few mm to a few cm from the points, the floor through them: held, the QPs."""
    rng = np.random.default_rng(seed)
    solver = _native_solver(human)
    solver.step(Frame(0.0, dict(zip(SENSOR_SEGMENTS,
                                    random_rotations(len(SENSOR_SEGMENTS), rng)))))
    tasks, s, conf = solver.tasks, solver.settings, solver._configuration
    native = solver._projection
    frames = tasks.contact.frame_ids
    answers = set()
    for _ in range(40):
        q = human.neutral()
        for joint in human.ball_joints.values():
            axis = rng.normal(size=3) * 0.3
            q[joint.idx_q:joint.idx_q + 4] = pin.Quaternion(pin.exp3(axis)).coeffs()
        conf.update(q)
        P = conf.positions(frames)
        k = len(frames)
        planted = rng.random(k) < 0.4
        offset = rng.normal(size=(k, 3)) * 10.0 ** rng.uniform(-3, -1.3)
        tasks.contact.set_anchors(planted, P + offset, planted & (rng.random(k) < 0.3))
        tasks.floor.floor_z = float(P[:, 2].min() - rng.uniform(-0.01, 0.02))
        if tasks.contact.world_rows() is None:
            continue
        args = (tasks.contact, tasks.floor, solver._range_rows, frames,
                s.constraint_tolerance, s.projection_steps, s.backend, s.qp)
        relaxed = projection_module.project_on_contacts(conf, *args)
        reference = conf.q.copy()
        conf.update(q)
        assert projection_module.project_on_contacts(conf, *args, native) == relaxed
        np.testing.assert_allclose(conf.q, reference, rtol=0, atol=LOOSE)
        conf.update(q)
        answers.add(native.project(tasks.contact, tasks.floor, s.constraint_tolerance,
                                   s.projection_steps))
    assert answers >= {0, 1}  # held and handed to the QPs


def test_without_a_compiler_the_python_loop_projects(
        human: HumanModel, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IKFUSION_NO_COMPILE", "1")
    solver = Solver(human, contacts=True)
    assert solver._projection is None
    assert native_projection(solver._configuration, solver.tasks.contact) is None
