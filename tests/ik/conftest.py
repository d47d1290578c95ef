"""Fixtures for the solver tests: the model and smooth motions with known truth."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from ikfusion.ik.tree_solve import TreeClosedForm, tree_closed_form
from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.model import HumanModel
from ikfusion.native.build import find_compiler
from ikfusion.sim.capture import motion_from_bvh

CARTWHEELS = (Path(__file__).resolve().parents[2] / "benchmarks" / "motions"
              / "cmu_49_08_cartwheels_amp.bvh.gz")


@pytest.fixture(scope="session")
def human() -> HumanModel:
    return HumanModel.default()


@pytest.fixture(scope="session")
def tree(human: HumanModel) -> TreeClosedForm:
    """The native closed-form kernel of the default model (skipped without one)."""
    made = tree_closed_form(human.model)
    if made is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    return made


@pytest.fixture(scope="session")
def cartwheels() -> TruthMotion:
    """Two cartwheels of the motion library (CMU 49_08, 4.8 s at 60 Hz)."""
    return motion_from_bvh(CARTWHEELS, rate=60.0)


@pytest.fixture
def compile_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty native-code cache of this test (``$IKFUSION_CACHE``), a C compiler required."""
    if find_compiler() is None or shutil.which("cc") is None:
        pytest.skip("no C compiler on this machine")
    folder = tmp_path / "cache"
    monkeypatch.setenv("IKFUSION_CACHE", str(folder))
    monkeypatch.delenv("IKFUSION_NO_COMPILE", raising=False)
    return folder
