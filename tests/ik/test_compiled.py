"""The compiled step function equals the NumPy tasks and Pinocchio's kinematics."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from motions import smooth_motion

from ikfusion.ik import Configuration, Frame, Solver, compiled
from ikfusion.ik.compiled import CompiledKinematics
from ikfusion.ik.limits import JointRangeLimit
from ikfusion.ik.tasks import OrientationTask, PostureTask
from ikfusion.model import SENSOR_SEGMENTS, Body, HumanModel
from ikfusion.rotations import random_rotations


@pytest.mark.parametrize("height", [1.55, 1.95])
def test_compiled_residuals_equal_reference(rng, height: float) -> None:
    model = HumanModel.from_body(Body.from_height(height))
    segments = list(SENSOR_SEGMENTS)
    frames = [model.segment_frame_id(s) for s in segments]
    sites = [model.site_frame_id(s) for s in model.site_names]
    kin = CompiledKinematics(model.model, frames, list(model.ball_joints.values()), sites)
    geometry = kin.geometry(model.model)
    orientation = OrientationTask(frames, segments)
    posture = PostureTask.from_joints(model.ball_joints, {}, 1.0)
    limits = JointRangeLimit(model.ball_joints, margin_deg=25.0)
    for _ in range(5):
        q = model.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        T = random_rotations(len(segments), rng)
        orientation.set_targets(T, np.ones(len(segments)))
        conf = Configuration(model.model, q)
        w_or = rng.uniform(0.0, 2.0, 3 * len(segments))
        w_post = rng.uniform(0.0, 2.0, 3 * len(model.ball_joints))
        H, c, e_or, angles, E_inv, p, J = kin(q, T, geometry, w_or, w_post)
        np.testing.assert_allclose(e_or[:, 0], orientation.compute_error(conf), atol=1e-10)
        J_or = orientation.compute_jacobian(conf)
        J_post = posture.compute_jacobian(conf)
        e_post = posture.compute_error(conf)
        H_ref = J_or.T @ (w_or[:, None] * J_or) + J_post.T @ (w_post[:, None] * J_post)
        c_ref = J_or.T @ (w_or * e_or[:, 0]) + J_post.T @ (w_post * e_post)
        np.testing.assert_allclose(H, H_ref, atol=1e-9)
        np.testing.assert_allclose(c[:, 0], c_ref, atol=1e-9)
        a = limits.angles(q)
        np.testing.assert_allclose(angles.reshape(-1, 3), a, atol=1e-10)
        np.testing.assert_allclose(E_inv.reshape(-1, 3, 3), limits.rate_matrices(a), atol=1e-9)
        np.testing.assert_allclose(p.reshape(-1, 3), conf.positions(sites), atol=1e-12)
        np.testing.assert_allclose(J.reshape(-1, 3, model.model.nv), conf.linear_jacobians(sites),
                                   atol=1e-12)


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


def test_compiled_sensed_pose_equals_numpy(human: HumanModel, rng) -> None:
    """The sensed pose and its contact points: the compiled function and the NumPy version."""
    solver = Solver(human)
    assert solver._kinematics is not None and solver._kinematics.sensed_function is not None
    n = len(human.segment_names)
    for trial in range(6):
        q = human.random_configuration(rng, p_world_pelvis=rng.normal(size=3))
        T = random_rotations(n, rng)
        tracked = rng.random(n) < (0.3, 0.6, 0.9, 1.0, 1.0, 1.0)[trial]
        solver.orientation_task.set_targets(T, tracked.astype(float))
        q_sensed, p_sensed = solver._sensed_pose(q, tracked)
        np.testing.assert_allclose(q_sensed, solver._sensed_configuration(q, tracked, False),
                                   atol=1e-10)
        np.testing.assert_allclose(
            p_sensed, solver._contact_positions(solver._sensed_configuration(q, tracked)),
            atol=1e-10)


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


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty compile cache of this test, with a C compiler required."""
    if compiled.find_compiler() is None or shutil.which("cc") is None:
        pytest.skip("no C compiler on this machine")
    folder = tmp_path / "cache"
    monkeypatch.setenv("IKFUSION_CACHE", str(folder))
    monkeypatch.delenv("IKFUSION_NO_COMPILE", raising=False)
    return folder


def test_first_build_says_so_once_and_the_second_run_loads_it(
        cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    functions, warning = compiled.native_functions([_scaling(2.0)], "probe")
    assert warning is None and functions is not None
    np.testing.assert_allclose(np.asarray(functions[0]([1.0, 2.0])).ravel(), [2.0, 4.0])
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "compiling" in lines[0]
    again, _ = compiled.native_functions([_scaling(2.0)], "probe")
    assert again is not None and capsys.readouterr().err == ""


def test_a_tampered_cached_library_is_rebuilt_not_loaded(
        cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    compiled.native_functions([_scaling(2.0)], "probe")
    (library,) = cache.glob("*.so")
    # A valid library under the same name and symbol that computes something else.
    _compile_directly(_scaling(3.0), cache / "other.so")
    os.replace(cache / "other.so", library)
    capsys.readouterr()
    functions, warning = compiled.native_functions([_scaling(2.0)], "probe")
    assert warning is None and functions is not None
    np.testing.assert_allclose(np.asarray(functions[0]([1.0, 2.0])).ravel(), [2.0, 4.0])
    assert "does not match" in capsys.readouterr().err
    np.testing.assert_allclose(  # the rebuilt library is the right one again
        np.asarray(ca.external("ik_cache_probe", str(library))([1.0, 1.0])).ravel(), [2.0, 2.0])


def test_the_cache_key_changes_when_the_generating_source_changes(
        cache: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    compiler = str(compiled.find_compiler())
    before = compiled.library_path(cache, "probe", compiler)
    assert ca.CasadiMeta.version() in before.name
    compiled.native_functions([_scaling(2.0)], "probe")
    monkeypatch.setattr(compiled, "generator_fingerprint", lambda: "edited source")
    after = compiled.library_path(cache, "probe", compiler)
    assert after != before
    capsys.readouterr()
    compiled.native_functions([_scaling(2.0)], "probe")
    assert "compiling" in capsys.readouterr().err  # built anew, the old one not reused
    assert sorted(cache.glob("*.so")) == sorted([before, after])


def test_a_failed_compile_is_a_warning_of_the_solve(
        cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, human: HumanModel,
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
    assert not list(cache.glob("*.so"))
