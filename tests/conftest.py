"""Shared test fixtures: the real recordings under ../shared/data and seeded random generators."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

# The suite checks the Python modules (the reference): its checks that replace a function of a
# module see the replacement only there. tests/test_typed_modules.py runs the compiled ones
# (:mod:`ikfusion.native.typed_modules`) in subprocesses against them.
os.environ["IKFUSION_NO_TYPED"] = "1"


@pytest.fixture
def shared_data() -> Path:
    """``../shared/data`` beside the clone; the test skips with a reason when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real recordings not available: {SHARED_DATA} is absent (a user's clone)")
    return SHARED_DATA


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator so failures reproduce."""
    return np.random.default_rng(20261122)
