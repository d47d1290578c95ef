"""Fixtures for the solver tests: the model and smooth motions with known truth."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikfusion.mocap.model_motion import TruthMotion
from ikfusion.model import HumanModel
from ikfusion.sim.capture import motion_from_bvh

CARTWHEELS = (Path(__file__).resolve().parents[2] / "benchmarks" / "motions"
              / "cmu_49_08_cartwheels_amp.bvh.gz")


@pytest.fixture(scope="session")
def human() -> HumanModel:
    return HumanModel.default()


@pytest.fixture(scope="session")
def cartwheels() -> TruthMotion:
    """Two cartwheels of the motion library (CMU 49_08, 4.8 s at 60 Hz)."""
    return motion_from_bvh(CARTWHEELS, rate=60.0)
