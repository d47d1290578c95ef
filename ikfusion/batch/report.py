"""``DIR/batch_report.csv``: one row per finished input, and the batch's exit code."""

from __future__ import annotations

import csv
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..atomic import atomic_write

#: The report file name under the batch output folder.
REPORT_NAME = "batch_report.csv"
#: Its columns.
REPORT_COLUMNS: tuple[str, ...] = ("input", "status", "error", "frames", "seconds")


@dataclass(frozen=True)
class JobResult:
    """How one input of a batch ended.

    Args:
        input: The input as given (its label).
        name: Its output folder name under the batch folder.
        status: ``"ok"``, ``"skipped"`` (already done with the same fingerprint) or ``"failed"``.
        error: Why it failed (an input error names file, line and field), else ``""``.
        frames: Frames in its output (also for skipped inputs).
        seconds: Wall time spent on it in this run [s].
        bad_input: The failure was bad input (exit code 2) rather than an internal error (1).
    """

    input: str
    name: str
    status: str
    error: str = ""
    frames: int = 0
    seconds: float = 0.0
    bad_input: bool = False


def write_report(path: Path, results: Iterable[JobResult]) -> Path:
    """Write the report CSV atomically (a reader never sees half of it)."""
    with atomic_write(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(REPORT_COLUMNS)
        for r in results:
            writer.writerow([r.input, r.status, r.error, r.frames, f"{r.seconds:.3f}"])
    return path


def exit_code(results: Sequence[JobResult]) -> int:
    """0 when every input is ok or skipped, 1 if any failed internally, else 2 (bad input)."""
    failed = [r for r in results if r.status == "failed"]
    if not failed:
        return 0
    return 2 if all(r.bad_input for r in failed) else 1


def counts(results: Sequence[JobResult]) -> dict[str, int]:
    """How many inputs ended with each status."""
    out = {"ok": 0, "skipped": 0, "failed": 0}
    for r in results:
        out[r.status] = out.get(r.status, 0) + 1
    return out
