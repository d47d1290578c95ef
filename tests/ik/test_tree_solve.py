"""The native closed-form step on the kinematic tree (ikfusion.ik.tree_solve) against dense
linear algebra (the KKT system solved by NumPy) and against the LAPACK path of the solver."""

from __future__ import annotations

import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import ikfusion.ik.tree_solve as tree_solve
from ikfusion.ik import Solver
from ikfusion.ik.qp import QpBuffer
from ikfusion.ik.tree_solve import (
    CROSSES,
    FAILED,
    NOT_TREE,
    SOLVED,
    ancestors,
    column_parents,
)
from ikfusion.model import SENSOR_SEGMENTS, HumanModel
from ikfusion.native.kernel import kernel_path, kernel_source, native_kernel
from ikfusion.sim.gait import GaitParameters, generate_gait
from ikfusion.sim.truth import orientation_frames

SOURCE = kernel_source(tree_solve.__name__, "tree_solve.c")


@pytest.fixture(scope="module")
def model() -> HumanModel:
    return HumanModel.default()


def _related(model: HumanModel) -> np.ndarray:
    """(nv, nv) whether two tangent columns are one joint's or ancestor and descendant, from
    Pinocchio's own support lists (the joints from the root to each joint)."""
    m = model.model
    joint_of = np.zeros(m.nv, dtype=int)
    for j in range(1, m.njoints):
        joint_of[m.joints[j].idx_v:m.joints[j].idx_v + m.joints[j].nv] = j
    supports = [set(m.supports[j]) for j in range(m.njoints)]
    return np.array([[int(joint_of[a]) in supports[int(joint_of[k])]
                      or int(joint_of[k]) in supports[int(joint_of[a])] for a in range(m.nv)]
                     for k in range(m.nv)])


@pytest.mark.parametrize("build", ["human", "buildSampleModelHumanoidRandom",
                                   "buildSampleModelHumanoid", "buildSampleModelManipulator"])
def test_the_column_parents_are_pinocchios_row_parents(model: HumanModel, build: str) -> None:
    m = model.model if build == "human" else getattr(pin, build)()
    np.testing.assert_array_equal(column_parents(m), np.array(pin.Data(m).parents_fromRow))


def test_the_column_tree_is_pinocchios_joint_tree(model: HumanModel) -> None:
    chains = ancestors(column_parents(model.model))
    related = _related(model)
    mine = np.eye(model.model.nv, dtype=bool)
    for k, chain in enumerate(chains):
        assert all(a < k for a in chain)
        mine[k, chain] = mine[chain, k] = True
    np.testing.assert_array_equal(mine, related)


def _tree_problem(rng: np.random.Generator, model: HumanModel, m_eq: int
                  ) -> tuple[np.ndarray, ...]:
    """A positive definite H on the tree's pattern, c, and m_eq equality rows."""
    n = model.model.nv
    B = rng.standard_normal((n, n))
    H = (B @ B.T) * _related(model)
    H += np.diag(np.abs(H).sum(axis=1) + 0.1)  # diagonally dominant: positive definite
    return H, rng.standard_normal(n), rng.standard_normal((m_eq, n)), rng.standard_normal(m_eq)


def _solve(tree: tree_solve.TreeClosedForm, H: np.ndarray, c: np.ndarray, A: np.ndarray,
           b: np.ndarray, G: np.ndarray | None = None, h: np.ndarray | None = None) -> int:
    G = np.zeros((0, len(c))) if G is None else G
    h = np.zeros(0) if h is None else h
    p = QpBuffer(len(c), tree).views(len(h), len(b))
    p.H[:], p.c[:], p.G[:], p.h[:], p.A[:], p.b[:] = H, c, G, h, A, b
    assert p.packed is not None
    return tree.solve(p.packed, len(h), len(b))


@pytest.mark.parametrize("m_eq", [0, 3, 12])
def test_the_kernel_solves_the_kkt_system(tree, model, m_eq: int) -> None:
    rng = np.random.default_rng(m_eq)
    H, c, A, b = _tree_problem(rng, model, m_eq)
    assert _solve(tree, H, c, A, b) == SOLVED
    n = len(c)
    kkt = np.block([[H, A.T], [A, np.zeros((m_eq, m_eq))]])
    expected = np.linalg.solve(kkt, np.concatenate([-c, b]))[:n]
    np.testing.assert_allclose(tree.x, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_an_objective_off_the_tree_is_refused(tree, model) -> None:
    H, c, A, b = _tree_problem(np.random.default_rng(1), model, 3)
    k, a = np.argwhere(~_related(model) & np.tri(len(c), dtype=bool))[0]  # e.g. two legs
    H[k, a] = H[a, k] = 1e-3
    assert _solve(tree, H, c, A, b) == NOT_TREE


def test_a_crossed_row_dependent_rows_and_an_indefinite_objective(tree, model) -> None:
    H, c, A, b = _tree_problem(np.random.default_rng(2), model, 3)
    assert _solve(tree, H, c, A, b) == SOLVED
    x = tree.x.copy()
    G = np.vstack([np.eye(len(c))[:2], -np.eye(len(c))[:1]])
    assert _solve(tree, H, c, A, b, G, G @ x + 1e-9) == SOLVED
    cut = G @ x + 1e-9
    cut[2] -= 1e-6  # one row cuts through the minimiser
    assert _solve(tree, H, c, A, b, G, cut) == CROSSES
    np.testing.assert_allclose(tree.x, x, rtol=0, atol=1e-14)
    assert _solve(tree, H, c, np.vstack([A, A[:1]]), np.append(b, b[0])) == FAILED
    H[5, 5] = -1.0
    assert _solve(tree, H, c, A, b) == FAILED


def test_the_solver_gives_the_lapack_paths_poses(tree, model) -> None:
    truth = generate_gait(model, GaitParameters(duration=3.0, stand=1.0), rate=60.0)
    frames = orientation_frames(model, truth.q, truth.time, SENSOR_SEGMENTS)
    for contacts in (True, False):
        poses = []
        for native in (True, False):
            solver = Solver(model, backend="daqp", contacts=contacts)
            assert solver.compiled is not None
            assert (solver.compiled.buffer.tree is not None) == (tree is not None)
            if not native:
                solver.compiled.buffer.tree = None
            poses.append(solver.solve(frames).q)
        assert np.abs(poses[0] - poses[1]).max() < 1e-9


def test_the_kernel_is_built_once_said_so_and_a_tampered_copy_is_rebuilt(
        compile_cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    library, warning = native_kernel(SOURCE)
    assert library is not None and warning is None
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "compiling" in lines[0]
    again, _ = native_kernel(SOURCE)
    assert again is not None and capsys.readouterr().err == ""
    (built,) = compile_cache.glob("tree_solve_*.so")
    other = tmp_path / "other.c"  # a valid library with the same symbol doing something else
    other.write_text("int ik_tree_closed_form(void) { return 7; }\n")
    subprocess.run(["cc", "-shared", "-fPIC", str(other), "-o", str(tmp_path / "other.so")],
                   check=True, capture_output=True)
    os.replace(tmp_path / "other.so", built)
    rebuilt, _ = native_kernel(SOURCE)
    assert rebuilt is not None and "does not match" in capsys.readouterr().err
    chain = tree_solve.TreeClosedForm(rebuilt, np.array([-1, 0, 1]))  # the real kernel again
    packed = np.concatenate([np.diag([2.0, 4.0, 8.0]).ravel(), [2.0, 2.0, 2.0]])
    assert chain.solve(packed, 0, 0) == SOLVED
    np.testing.assert_allclose(chain.x, [-1.0, -0.5, -0.25])


@pytest.mark.parametrize("module", ["native.kernel", "native.build"])
def test_the_kernels_cache_key_covers_its_build_code(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, module: str) -> None:
    """Editing the code that builds the kernel builds it anew (a new library name)."""
    import importlib

    target = importlib.import_module(f"ikfusion.{module}")
    before = kernel_path(SOURCE, tmp_path, "cc")
    edited = tmp_path / "edited.py"
    edited.write_bytes(Path(str(target.__file__)).read_bytes() + b"\n# edited\n")
    monkeypatch.setattr(target, "__file__", str(edited))
    assert kernel_path(SOURCE, tmp_path, "cc") != before


def test_without_a_compiler_there_is_no_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IKFUSION_NO_COMPILE", "1")
    assert native_kernel(SOURCE) == (None, None)


def test_a_problem_holding_nan_is_refused_by_name_through_the_kernel(tree, model) -> None:
    from ikfusion.errors import SolverError
    from ikfusion.ik.qp import solve_qp
    from ikfusion.ik.settings import SolverSettings

    H, c, A, b = _tree_problem(np.random.default_rng(3), model, 3)
    c[4] = np.nan
    assert _solve(tree, H, c, A, b) == tree_solve.NOT_FINITE
    p = QpBuffer(len(c), tree).views(0, 3)
    p.H[:], p.c[:], p.A[:], p.b[:] = H, c, A, b
    with pytest.raises(SolverError, match="c \\(targets\\)"):
        solve_qp(p, "daqp", SolverSettings.load().qp)


def test_the_kernels_finite_check_is_numpys_sum(tree, model) -> None:
    """Finite numbers overflowing a running sum but not NumPy's pairwise one (the sum
    qp._check_finite takes) are passed on; those overflowing NumPy's too are refused."""
    H, c, A, b = _tree_problem(np.random.default_rng(4), model, 3)
    p = QpBuffer(len(c), tree).views(0, 3)
    p.H[:], p.c[:], p.A[:], p.b[:] = H, c, A, b
    assert p.packed is not None
    p.packed[[1, 2]] = 1e308  # H's upper triangle (never read): 1e308 + 1e308 overflows
    p.packed[[9, 10]] = -1e308  # but NumPy adds each to one of these first
    assert math.isfinite(np.add.reduce(p.packed))
    assert tree.solve(p.packed, 0, 3) == SOLVED
    p.packed[[9, 10]] = 1e308
    with np.errstate(over="ignore"):
        assert not math.isfinite(np.add.reduce(p.packed))
    assert tree.solve(p.packed, 0, 3) == tree_solve.NOT_FINITE
