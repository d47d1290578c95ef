"""benchmarks/phase_excess.py: each step's cause, and a phase's excess shared out by them."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _tool():
    """``benchmarks/phase_excess.py`` as a module (benchmarks/ is not a package)."""
    name = "phase_excess_under_test"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / "phase_excess.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def test_each_step_gets_the_cause_of_what_the_solver_held() -> None:
    tool = _tool()
    held = np.array([[1, 0], [1, 0], [1, 0], [1, 0], [0, 1], [0, 0]], dtype=bool)
    z = np.array([[0.0, 0.0], [-0.05, 0.0], [-0.01, 0.0], [0.01, 0.0], [0.0, -0.05],
                  [0.0, 0.0]])
    causes = [tool.CAUSES[c] for c in tool.step_causes(held, z, ["Sacrum", "LeftHeel"])]
    assert causes == ["sunk", "under", "held", "switch", "free"]


def test_the_excess_is_shared_out_by_path_length() -> None:
    tool = _tool()
    relative = np.array([[0.0, 0.0], [0.003, 0.0], [0.003, 0.001]])
    parts = tool.cause_split(0.008, relative, np.array([0, 3]))
    np.testing.assert_allclose(parts, [0.006, 0.0, 0.0, 0.002, 0.0])
    assert not tool.cause_split(0.0, np.zeros((3, 2)), np.array([0, 1])).any()
