"""A short solved motion written as a result folder, shared by the viewer tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from view_motion import stepping_motion

from ikfusion.model import HumanModel
from ikfusion.results import write_result_folder


@pytest.fixture(scope="session")
def human() -> HumanModel:
    """The default subject."""
    return HumanModel.default()


@pytest.fixture(scope="session")
def result_folder(human: HumanModel, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A result folder of :func:`stepping_motion`, with a two-reader constellation."""
    out = write_result_folder(stepping_motion(human), tmp_path_factory.mktemp("view") / "result")
    (out / "readers.yaml").write_text(
        "readers:\n"
        "  - {id: R1, position: [-1.0, -2.0, 2.5], clock_offset: 0.0}\n"
        "  - {id: R2, position: [3.0, 2.0, 2.5], clock_offset: 0.0}\n")
    return out
