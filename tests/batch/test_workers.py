"""Local batch workers start warm: forked from one server that imported the job kind once."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from ikfusion.batch.workers import WARM_METHOD, start_method  # noqa: E402

HERE = Path(__file__).resolve().parent

#: A fresh process runs the batch (the warm server lives as long as its process: one started by
#: another test would have imported other modules).
RUN_PROBE = """
import sys
from probe_kind import PROBE
from ikfusion.batch.runner import run_batch
outcome = run_batch(PROBE, [sys.argv[1]], sys.argv[2], {}, workers=2, progress=False)
sys.exit(outcome.exit_code)
"""


@pytest.mark.skipif(start_method() != WARM_METHOD, reason="no forkserver on this platform")
def test_two_workers_share_one_import_of_the_job_kind(tmp_path: Path) -> None:
    """Neither worker imports the kind's module itself: both inherit the server's import."""
    inputs = tmp_path / "in"
    inputs.mkdir()
    for i in range(8):
        (inputs / f"input{i}.txt").write_text(f"{i}\n")
    out = tmp_path / "out"
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        [sys.executable, "-c", RUN_PROBE, str(inputs / "*.txt"), str(out)], cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), str(root)])},
        capture_output=True,
        text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    runs = [json.loads((out / f"input{i}" / "process.json").read_text()) for i in range(8)]
    assert len({r["pid"] for r in runs}) == 2  # both workers took inputs
    assert not any(r["imported_here"] for r in runs)
