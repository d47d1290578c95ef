"""The real Xsens walk solved natively, for the tests of the native kernels."""

from __future__ import annotations

from pathlib import Path

import pytest

from ikfusion.cli import main
from ikfusion.native.build import usable_compiler


def solve_real_walk_natively(out: Path) -> None:
    """``ikfusion solve`` of the real Xsens walk into ``out``, its kernels compiled.

    Skips (with the reason) without ../shared's recordings or without a C compiler (or with
    ``IKFUSION_NO_COMPILE``), where the native kernels are not built.
    """
    trial = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "xsens" / \
        "opensense_walk"
    if not trial.is_dir():
        pytest.skip(f"real recordings not available: {trial} is absent (a user's clone)")
    if usable_compiler() is None:
        pytest.skip("no C compiler (or IKFUSION_NO_COMPILE): the kernel is not built")
    assert main(["solve", "--imu", str(trial), "--map", str(trial / "myIMUMappings.xml"),
                 "--out", str(out), "--quiet"]) == 0
