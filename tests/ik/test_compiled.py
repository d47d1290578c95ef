"""The compiled step function equals the NumPy tasks and Pinocchio's kinematics."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from motions import smooth_motion

from ikfusion.ik import Configuration, Frame, Solver, SolverSettings, compiled, native
from ikfusion.ik.compiled import CompiledKinematics
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.ik.limits.joint_range import LinearisedRanges
from ikfusion.ik.tasks import (
    ChainShareTask,
    DampingTask,
    EvenChainTask,
    OrientationTask,
    PostureTask,
)
from ikfusion.model import SENSOR_SEGMENTS, Body, HumanModel
from ikfusion.model.angle_continuity import nearest_to_ranges
from ikfusion.paths import module_source
from ikfusion.rotations import exp_so3, random_rotations


def _near_half_turns(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rotations by angles in [pi - 1e-6, pi] about random axes."""
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return exp_so3(axes * (np.pi - rng.uniform(0.0, 1e-6, n))[:, None])


@pytest.mark.parametrize(("height", "case"), [(1.55, "random"), (1.95, "random"),
                                              (1.75, "near pi")])
def test_compiled_residuals_equal_reference(rng, height: float, case: str) -> None:
    """The compiled outputs equal the NumPy tasks, limits and Pinocchio's kinematics.

    The posture references are random (not the identity); in the "near pi" case every
    orientation error and every posture error is a rotation by pi - 1e-6 or more. The even-chain
    and the chain-share pairs (each a random subset active, the share holding a random last
    frame) and the persistence task (random weights on the joints, a random reference) are
    summed into the objective too.
    """
    model = HumanModel.from_body(Body.from_height(height))
    segments = list(SENSOR_SEGMENTS)
    frames = [model.segment_frame_id(s) for s in segments]
    sites = [model.site_frame_id(s) for s in model.site_names]
    chain = EvenChainTask(model.ball_joints, SolverSettings.load().even_chains, 1.5,
                          model.segment_names)
    share = ChainShareTask(model.ball_joints, SolverSettings.load().even_chains, 4.0,
                           model.segment_names)
    persistence = DampingTask(np.zeros(model.model.nv))
    kin = CompiledKinematics(model.model, frames, list(model.ball_joints.values()), sites,
                             chain_pairs=chain.pairs)
    geometry = kin.geometry(model.model)
    np.testing.assert_array_equal(kin.persistence_excluded, np.arange(6))  # the free-flyer
    orientation = OrientationTask(frames, segments)
    posture = PostureTask.from_joints(model.ball_joints, {}, 1.0)
    limits = JointRangeLimit(model.ball_joints, margin_deg=25.0)
    n_joints = len(model.ball_joints)
    for _ in range(5):
        q = model.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        conf = Configuration(model.model, q)
        if case == "near pi":  # R T^T and R_ref^T R_joint are half turns, or nearly
            T = np.swapaxes(_near_half_turns(len(segments), rng), 1, 2) @ conf.rotations(frames)
            R_joint = posture._joint_rotations(q)
            R_ref = R_joint @ np.swapaxes(_near_half_turns(n_joints, rng), 1, 2)
        else:
            T = random_rotations(len(segments), rng)
            R_ref = random_rotations(n_joints, rng)
        w_frames = rng.uniform(0.0, 2.0, len(segments))
        orientation.set_targets(T, w_frames)
        posture.R_reference = R_ref
        posture.axis_weights = rng.uniform(0.0, 2.0, (n_joints, 3))  # per-row weights
        w_or, w_post = orientation.row_weights(), posture.row_weights()
        chain.active = rng.random(len(chain.pairs)) < 0.7
        share.active = rng.random(len(share.pairs)) < 0.7
        share.set_previous(model.random_configuration(rng))
        persistence.weights = rng.uniform(0.0, 3.0, model.model.nv)
        persistence.weights[kin.persistence_excluded] = 0.0  # the root's columns
        persistence.set_reference(model.random_configuration(rng))
        assert share.q_previous is not None and persistence.q_reference is not None
        H, c, e_or, angles, E_inv, p, J, G_ranges, room_up, room_down = kin(
            q, T, geometry, w_or, w_post, R_ref, (limits.lower, limits.upper),
            chain.row_weights(), (share.row_weights(), share.q_previous),
            (persistence.weights, persistence.q_reference))
        e_or_ref = orientation.compute_error(conf)
        if case == "near pi":
            e_post = posture.compute_error(conf).reshape(-1, 3)
            assert np.all(np.linalg.norm(e_or_ref.reshape(-1, 3), axis=1) > np.pi - 2e-6)
            assert np.all(np.linalg.norm(e_post, axis=1) > np.pi - 2e-6)
        np.testing.assert_allclose(e_or[:, 0], e_or_ref, atol=1e-8)
        # The objective the NumPy solver assembles from the same tasks.
        H_ref, c_ref = np.zeros_like(H), np.zeros(len(c))
        orientation.add_objective(conf, H_ref, c_ref)
        posture.add_objective(conf, H_ref, c_ref)
        chain.add_objective(conf, H_ref, c_ref)
        share.add_objective(conf, H_ref, c_ref)
        persistence.add_objective(conf, H_ref, c_ref)
        assert np.array_equal(H, H.T)  # one number per pair of columns (the lower triangle)
        np.testing.assert_allclose(H, H_ref, atol=1e-8 * np.abs(H_ref).max())
        np.testing.assert_allclose(c[:, 0], c_ref, atol=1e-8 * np.abs(c_ref).max())
        a = limits.angles(q)
        np.testing.assert_allclose(angles.reshape(-1, 3), a, atol=1e-10)
        np.testing.assert_allclose(E_inv.reshape(-1, 3, 3), limits.rate_matrices(a), atol=1e-9)
        ranges = limits.linearise(a, None, model.model.nv)  # the nearest triple, flipped rows
        np.testing.assert_allclose(G_ranges, ranges.G, atol=1e-9)
        np.testing.assert_allclose(room_up[:, 0], ranges.room_up, atol=1e-10)
        np.testing.assert_allclose(room_down[:, 0], ranges.room_down, atol=1e-10)
        np.testing.assert_allclose(p.reshape(-1, 3), conf.positions(sites), atol=1e-12)
        np.testing.assert_allclose(J.reshape(-1, 3, model.model.nv), conf.linear_jacobians(sites),
                                   atol=1e-12)


def test_quaternion_log_is_the_log_of_the_matrix(rng) -> None:
    """The compiled step's quaternion log (:mod:`ikfusion.ik.compiled_joint_tasks`) equals
    :func:`ikfusion.rotations.log_so3` of the quaternion's matrix, either sign of the
    quaternion, at angles from 1e-9 rad (its series) to nearly a half turn."""
    from ikfusion.ik.compiled_joint_tasks import quaternion_log
    from ikfusion.rotations import log_so3, quat_wxyz_to_matrix

    symbol = ca.SX.sym("q", 4)
    log = ca.Function("log", [symbol], [quaternion_log(symbol)])
    axes = rng.normal(size=(60, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([np.logspace(-9, 0, 30), rng.uniform(1.0, np.pi - 1e-6, 30)])
    for axis, angle in zip(axes, angles):
        xyzw = np.append(np.sin(angle / 2) * axis, np.cos(angle / 2))
        expected = log_so3(quat_wxyz_to_matrix(np.roll(xyzw, 1)))
        for sign in (1.0, -1.0):  # q and -q are one rotation
            got = np.asarray(log(sign * xyzw)).ravel()
            np.testing.assert_allclose(got, expected, atol=1e-14, rtol=1e-12)


def test_compiled_ranges_measure_on_the_triple_nearest_the_range(human: HumanModel,
                                                                 rng) -> None:
    """Joints turned anywhere (many beyond their range, on the other Euler branch): the
    compiled limit rows equal :meth:`JointRangeLimit.linearise`, flipped middle rows included."""
    joints = list(human.ball_joints.values())
    frames = [human.segment_frame_id(s) for s in SENSOR_SEGMENTS]
    kin = CompiledKinematics(human.model, frames, joints, [])
    limits = JointRangeLimit(human.ball_joints, margin_deg=25.0)
    flipped = 0
    for _ in range(5):
        q = human.neutral()
        for joint in joints:  # a uniformly random rotation (x, y, z, w)
            quaternion = rng.normal(size=4)
            q[joint.idx_q:joint.idx_q + 4] = quaternion / np.linalg.norm(quaternion)
        outputs = kin(q, random_rotations(len(frames), rng), kin.geometry(human.model),
                      np.ones(3 * len(frames)), np.ones(3 * len(joints)),
                      random_rotations(len(joints), rng), (limits.lower, limits.upper))
        a = limits.angles(q)
        flipped += int(nearest_to_ranges(a, limits.lower, limits.upper,
                                             limits.coupling)[1].sum())
        ranges = limits.linearise(a, None, human.model.nv)
        np.testing.assert_allclose(outputs[7], ranges.G, atol=1e-8)
        np.testing.assert_allclose(outputs[8][:, 0], ranges.room_up, atol=1e-10)
        np.testing.assert_allclose(outputs[9][:, 0], ranges.room_down, atol=1e-10)
    assert flipped > 0


def test_a_joint_at_gimbal_lock_makes_no_rows_of_its_undefined_angles() -> None:
    """The right shoulder exactly at its Euler lock (axial rotation 90 deg): its flexion and
    abduction are not defined there, only their sum (the compiled rates were NaN, NumPy's
    9e15), with the axial rotation's range reaching the lock (``rot: [-90, 90]``). The
    compiled and NumPy rows are finite and agree, and neither angle makes a row, though the
    principal triple puts the abduction at -90 deg, 40 deg past its limit (a row ``0 <= -40
    deg`` would be infeasible)."""
    human = HumanModel.from_body(Body(ranges=(("jRightShoulder", "rot", -90.0, 90.0),)))
    joints = list(human.ball_joints.values())
    frames = [human.segment_frame_id(s) for s in SENSOR_SEGMENTS]
    kin = CompiledKinematics(human.model, frames, joints, [])
    limits = JointRangeLimit(human.ball_joints, margin_deg=25.0)
    q = human.configuration({"jRightShoulder_flex": 170.0, "jRightShoulder_rot": 90.0,
                             "jRightShoulder_abd": -23.0})
    outputs = kin(q, np.tile(np.eye(3), (len(frames), 1, 1)), kin.geometry(human.model),
                  np.ones(3 * len(frames)), np.ones(3 * len(joints)),
                  np.tile(np.eye(3), (len(joints), 1, 1)), (limits.lower, limits.upper))
    n = list(human.ball_joints).index("jRightShoulder")
    a = limits.angles(q)
    assert np.degrees(a[n, 2]) == pytest.approx(-90.0) and limits.lower[n, 2] > a[n, 2] + 0.6
    numpy_rows = limits.linearise(a, None, human.model.nv)
    compiled_rows = LinearisedRanges(outputs[7], np.stack((outputs[8][:, 0], outputs[9][:, 0])))
    defined = np.arange(3 * len(joints)) != 3 * n + 1  # the middle angle's rate at the lock:
    for ranges in (compiled_rows, numpy_rows):       # a cone's apex, any direction
        assert np.all(np.isfinite(ranges.G))
        assert np.all(np.abs(ranges.G) < 1e3)
        np.testing.assert_allclose(ranges.G[defined], numpy_rows.G[defined], atol=1e-8)
        up, down = ranges.without_still_angles().near(limits.margin)
        undefined = [3 * n, 3 * n + 2]
        assert not np.any(up[undefined]) and not np.any(down[undefined])


def test_compiled_and_reference_solvers_agree(human: HumanModel, rng) -> None:
    qs = smooth_motion(human, rng, frames=30)
    data = human.model.createData()
    import pinocchio as pin

    frames = []
    for k, q in enumerate(qs):
        pin.framesForwardKinematics(human.model, data, q)
        frames.append(Frame(k / 60, {s: data.oMf[human.segment_frame_id(s)].rotation.copy()
                                     for s in SENSOR_SEGMENTS}))
    fast = Solver(human, contacts=False).solve(frames)
    reference = Solver(human, contacts=False, compiled=False).solve(frames)
    np.testing.assert_allclose(fast.q, reference.q, atol=1e-7)


@pytest.mark.parametrize("evaluation", ["native", "virtual machine"])
def test_solvers_agree_with_a_posture_reference(
        human: HumanModel, rng, evaluation: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A non-identity posture reference reaches the compiled step (native or CasADi's VM)."""
    if evaluation == "native":
        if native.find_compiler() is None:
            pytest.skip("no C compiler on this machine")
        monkeypatch.delenv("IKFUSION_NO_COMPILE", raising=False)
    else:
        monkeypatch.setenv("IKFUSION_NO_COMPILE", "1")
    monkeypatch.setattr(compiled, "_BUILT", {})
    import pinocchio as pin

    qs = smooth_motion(human, rng, frames=10)
    data = human.model.createData()
    frames = []
    for k, q in enumerate(qs):
        pin.framesForwardKinematics(human.model, data, q)
        frames.append(Frame(k / 60, {s: data.oMf[human.segment_frame_id(s)].rotation.copy()
                                     for s in SENSOR_SEGMENTS[:8]}))  # the rest: the prior
    R_reference = exp_so3(rng.normal(scale=0.5, size=(len(human.ball_joints), 3)))
    solvers = [Solver(human, contacts=False), Solver(human, contacts=False, compiled=False)]
    assert solvers[0].compiled is not None and solvers[1].compiled is None
    for solver in solvers:
        solver.tasks.posture.R_reference = R_reference
    fast, reference = (solver.solve(frames) for solver in solvers)
    np.testing.assert_allclose(fast.q, reference.q, atol=1e-7)
    plain = Solver(human, contacts=False, compiled=False).solve(frames)
    assert np.abs(plain.q - reference.q).max() > 1e-3  # the reference matters


def _random_step_inputs(human: HumanModel, kinematics, geometry: np.ndarray,
                        rng: np.random.Generator) -> tuple:
    """Inputs of the step function at a random configuration, targets, weights and ranges."""
    k, j = len(kinematics.segment_frames), len(human.ball_joints)
    q = human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
    return (q, random_rotations(k, rng), geometry, rng.uniform(0.0, 2.0, 3 * k),
            rng.uniform(0.0, 2.0, 3 * j), random_rotations(j, rng),
            (-rng.uniform(0.1, 2.0, 3 * j), rng.uniform(0.1, 2.0, 3 * j)))


def test_the_step_without_sites_is_the_step_bit_for_bit(human: HumanModel, rng) -> None:
    """The step function without the sites (a step weighing none, orientations alone) gives
    every other output bit for bit as the full one (the same operations), the sites zero."""
    solver = Solver(human, contacts=False)
    assert solver.compiled is not None
    kinematics, geometry = solver.compiled.kinematics, solver.compiled.geometry
    for _ in range(3):
        inputs = _random_step_inputs(human, kinematics, geometry, rng)
        full = [o.copy() for o in kinematics(*inputs)]
        bare = kinematics.evaluate(*inputs, sites=False)
        for i, name in enumerate(kinematics.function.name_out()):
            if name in ("p_sites", "J_sites"):
                assert not bare.output(i).any()
            else:
                assert np.array_equal(bare.output(i), full[i], equal_nan=True), name


def test_the_step_with_the_contacts_only_is_the_step_bit_for_bit(human: HumanModel,
                                                                  rng) -> None:
    """The step function with only the contact points' and the root's sites gives their rows
    of the sites and every other output bit for bit as the full one (the same operations)."""
    solver = Solver(human)
    assert solver.compiled is not None and solver.compiled.contacts_only
    kinematics, geometry = solver.compiled.kinematics, solver.compiled.geometry
    rows = kinematics.point_rows
    assert rows is not None and rows[:-1] == solver.tasks.contact_rows.tolist()
    assert rows[-1] == len(kinematics.site_frames) - 1  # the root
    for _ in range(3):
        inputs = _random_step_inputs(human, kinematics, geometry, rng)
        full = [o.copy() for o in kinematics(*inputs)]
        few = kinematics.evaluate(*inputs, sites=None)
        for i, name in enumerate(kinematics.function.name_out()):
            expected = full[i]
            if name in ("p_sites", "J_sites"):
                expected = expected.reshape(len(kinematics.site_frames), 3, -1)[rows]
            assert np.array_equal(few.output(i).reshape(expected.shape), expected,
                                  equal_nan=True), name


def test_compiled_sensed_pose_equals_numpy(human: HumanModel, rng) -> None:
    """The sensed pose and its contact points: the compiled function and the NumPy version."""
    solver = Solver(human)
    assert solver.compiled is not None
    assert solver.compiled.kinematics.sensed_function is not None
    sensed = solver.sensed
    n = len(human.segment_names)
    for trial in range(6):
        q = human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        T = random_rotations(n, rng)
        tracked = rng.random(n) < (0.3, 0.6, 0.9, 1.0, 1.0, 1.0)[trial]
        q_sensed, p_sensed = sensed.pose(q, T, tracked)
        np.testing.assert_allclose(q_sensed, sensed.configuration(q, T, tracked, False),
                                   atol=1e-10)
        np.testing.assert_allclose(
            p_sensed, sensed.contact_positions(sensed.configuration(q, T, tracked)),
            atol=1e-10)


def test_sensed_pose_keeps_a_read_only_tracked_set_until_another_comes(human: HumanModel,
                                                                        rng) -> None:
    """The compiled sensed pose writes the tracked set only when it changes (a read-only
    array is kept): switching between two sets gives each set's pose, the writeable set (or
    memory) is read afresh every call, and a returned pose is not overwritten by the next
    call."""
    sensed = Solver(human).sensed
    n = len(human.segment_names)
    q = human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
    T = random_rotations(n, rng)
    every, some = np.ones(n, dtype=bool), rng.random(n) < 0.5
    for mask in (every, some):
        mask.setflags(write=False)
    free = some.copy()
    first = sensed.pose(q, T, every)
    kept = [a.copy() for a in first]
    for tracked in (some, every, free, some):
        got = sensed.pose(q, T, tracked)
        np.testing.assert_allclose(got[0], sensed.configuration(q, T, tracked, False),
                                   atol=1e-10)
        np.testing.assert_allclose(
            got[1], sensed.contact_positions(sensed.configuration(q, T, tracked)), atol=1e-10)
    free[:] = True  # changed in place: read again
    assert np.array_equal(sensed.pose(q, T, free)[0], sensed.pose(q, T, every)[0])
    base = some.copy()  # a read-only view of writeable memory, changed through it: read again
    view = base[:]
    view.setflags(write=False)
    expected = sensed.pose(q, T, some)[0].copy()
    assert np.array_equal(sensed.pose(q, T, view)[0], expected)
    base[:] = True
    assert np.array_equal(sensed.pose(q, T, view)[0], sensed.pose(q, T, every)[0])
    sensed.pose(q, T, some)
    some.setflags(write=True)  # the kept set made writeable again and changed: read again
    some[:] = True
    assert np.array_equal(sensed.pose(q, T, some)[0], sensed.pose(q, T, every)[0])
    for mine, before in zip(first, kept):
        assert np.array_equal(mine, before)


# --------------------------------------------------------------------------- the disk cache
def _scaling(factor: float) -> ca.Function:
    """A tiny function to compile quickly: x -> factor * x."""
    x = ca.SX.sym("x", 2)
    return ca.Function("ik_cache_probe", [x], [factor * x])


def _compile_directly(function: ca.Function, library: Path) -> None:
    """Build a library with plain CasADi and cc, independently of the code under test."""
    work = library.parent / "direct"
    work.mkdir()
    generator = ca.CodeGenerator("probe.c", {"with_header": False})
    generator.add(function)
    generator.generate(f"{work}{os.sep}")
    subprocess.run(["cc", "-shared", "-fPIC", str(work / "probe.c"), "-o", str(library), "-lm"],
                   check=True, capture_output=True)


def test_first_build_says_so_once_and_the_second_run_loads_it(
        compile_cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    functions, warning = native.native_functions([_scaling(2.0)], "probe")
    assert warning is None and functions is not None
    np.testing.assert_allclose(np.asarray(functions[0]([1.0, 2.0])).ravel(), [2.0, 4.0])
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "compiling" in lines[0]
    again, _ = native.native_functions([_scaling(2.0)], "probe")
    assert again is not None and capsys.readouterr().err == ""


def test_a_tampered_cached_library_is_rebuilt_not_loaded(
        compile_cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    native.native_functions([_scaling(2.0)], "probe")
    (library,) = compile_cache.glob("*.so")
    # A valid library under the same name and symbol that computes something else.
    _compile_directly(_scaling(3.0), compile_cache / "other.so")
    os.replace(compile_cache / "other.so", library)
    capsys.readouterr()
    functions, warning = native.native_functions([_scaling(2.0)], "probe")
    assert warning is None and functions is not None
    np.testing.assert_allclose(np.asarray(functions[0]([1.0, 2.0])).ravel(), [2.0, 4.0])
    assert "does not match" in capsys.readouterr().err
    np.testing.assert_allclose(  # the rebuilt library is the right one again
        np.asarray(ca.external("ik_cache_probe", str(library))([1.0, 1.0])).ravel(), [2.0, 2.0])


def test_the_cache_key_changes_when_the_generating_source_changes(
        compile_cache: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    compiler = str(native.find_compiler())
    before = native.library_path(compile_cache, "probe", compiler)
    assert ca.CasadiMeta.version() in before.name
    native.native_functions([_scaling(2.0)], "probe")
    monkeypatch.setattr(native, "generator_fingerprint", lambda: "edited source")
    after = native.library_path(compile_cache, "probe", compiler)
    assert after != before
    capsys.readouterr()
    native.native_functions([_scaling(2.0)], "probe")
    assert "compiling" in capsys.readouterr().err  # built anew, the old one not reused
    assert sorted(compile_cache.glob("*.so")) == sorted([before, after])


@pytest.mark.parametrize("module", ["rotations_casadi", "rotations", "ik.compiled",
                                    "ik.casadi_kinematics", "ik.native",
                                    "native.build"])
def test_the_cache_key_covers_the_rotation_modules(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, module: str) -> None:
    """The step's expressions live in these modules (SO(3) maps, the kinematics graph, the
    step and its build): editing any of them must rebuild."""
    import importlib

    name = importlib.import_module(f"ikfusion.{module}").__name__
    before = native.generator_fingerprint()
    edited = tmp_path / f"{module}.py"
    edited.write_bytes(module_source(name).read_bytes() + b"\n# edited\n")
    monkeypatch.setattr(native, "module_source",
                        lambda other: edited if other == name else module_source(other))
    assert native.generator_fingerprint() != before


def test_a_failed_compile_is_a_warning_of_the_solve(
        compile_cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, human: HumanModel,
        capsys: pytest.CaptureFixture[str]) -> None:
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "cc").write_text('#!/bin/sh\nif [ "$1" = --version ]; then echo fakecc 1.0; exit 0; '
                             'fi\necho "fatal error: disk quota exceeded" >&2\nexit 1\n')
    (fake / "cc").chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setattr(compiled, "_BUILT", {})
    solver = Solver(human, contacts=False)
    err = capsys.readouterr().err
    assert "warning" in err and "disk quota exceeded" in err
    frame = Frame(0.0, {s: np.eye(3) for s in SENSOR_SEGMENTS})
    motion = solver.solve([frame])
    assert any("compiling the solver's step function failed" in w for w in motion.warnings)
    assert not list(compile_cache.glob("*.so"))
