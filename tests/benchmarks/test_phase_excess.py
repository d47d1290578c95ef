"""benchmarks/phase_excess.py: each step's cause, and a phase's excess shared out by them."""

from __future__ import annotations

from types import ModuleType

import numpy as np
from benchmark_scripts import benchmark_script


def _tool() -> ModuleType:
    """``benchmarks/phase_excess.py`` as a module."""
    return benchmark_script("phase_excess.py")


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
