"""Start-up of the solver: no graph built when its library is cached, no qpsolvers for DAQP."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import ikfusion
from ikfusion.ik import compiled


def _two_segment_model() -> tuple[pin.Model, list[int]]:
    """A free-flyer with one spherical joint: small enough to compile in a second."""
    model = pin.Model()
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    child = model.addJoint(root, pin.JointModelSpherical(),
                           pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.4])), "ball")
    frames = [model.addFrame(pin.Frame(name, joint, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
              for name, joint in (("a", root), ("b", child))]
    return model, frames


def test_a_cached_library_is_loaded_without_building_the_graph(
        compile_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(compiled, "_BUILT", {})
    model, frames = _two_segment_model()
    first = compiled.compiled_kinematics(model, frames, [], [frames[1]])
    assert not first.warnings and list(compile_cache.glob("*.so"))
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    targets = np.stack([np.eye(3), np.eye(3)])
    args = (q, targets, first.geometry(model), np.ones(6), np.zeros(0), np.zeros((0, 3, 3)))
    expected = [a.copy() for a in first(*args)]

    def no_graph(*_: object) -> None:
        raise AssertionError("the graph was built although its library is cached")

    monkeypatch.setattr(compiled, "_BUILT", {})
    monkeypatch.setattr(compiled, "forward", no_graph)
    again = compiled.compiled_kinematics(model, frames, [], [frames[1]])
    for a, b in zip(again(*args), expected):
        np.testing.assert_array_equal(a, b)


def test_solving_with_daqp_does_not_import_qpsolvers(tmp_path: Path) -> None:
    """DAQP is called directly; qpsolvers (slow to import) only for the other backends."""
    script = (
        "import sys\n"
        "import numpy as np\n"
        "from ikfusion.ik import Frame, Solver\n"
        "from ikfusion.model import SENSOR_SEGMENTS, HumanModel\n"
        "solver = Solver(HumanModel.default(), backend='daqp')\n"
        "motion = solver.solve([Frame(t, {s: np.eye(3) for s in SENSOR_SEGMENTS})"
        " for t in (0.0, 0.02)])\n"
        "assert np.isfinite(motion.q).all()\n"
        "print('qpsolvers' in sys.modules)\n")
    env = {**os.environ, "IKFUSION_NO_COMPILE": "1",
           "PYTHONPATH": str(Path(ikfusion.__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, cwd=tmp_path, check=True, timeout=300)
    assert done.stdout.strip() == "False"
