"""Fixtures for the solver tests: the model and smooth motions with known truth."""

from __future__ import annotations

import pytest

from ikfusion.model import HumanModel


@pytest.fixture(scope="session")
def human() -> HumanModel:
    return HumanModel.default()
