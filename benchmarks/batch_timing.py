"""Batch throughput on 1 and 2 local Dask workers: the helper the benchmarks share.

``batch_rows`` runs :func:`ikfusion.batch.runner.run_batch` (what ``ikfusion batch`` runs) on
the same inputs once per worker count, each into a fresh temporary folder, and returns the
wall time (cluster start included) and the frames solved.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ikfusion.batch.kinds import load_kind
from ikfusion.batch.runner import run_batch


@dataclass(frozen=True)
class BatchRow:
    """One batch run: workers, wall time [s], inputs, inputs ok and frames solved."""

    workers: int
    seconds: float
    inputs: int
    ok: int
    frames: int


def batch_rows(kind: str, inputs: Sequence[str], options: Mapping[str, Any],
               workers: Sequence[int] = (1, 2)) -> list[BatchRow]:
    """Run ``batch KIND`` over ``inputs`` once per worker count (fresh output folders)."""
    rows = []
    job_kind = load_kind(kind)
    for n in workers:
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            outcome = run_batch(job_kind, list(inputs), Path(tmp) / "out", dict(options),
                                workers=n, progress=False)
            elapsed = time.perf_counter() - start
        ok = [r for r in outcome.results if r.status == "ok"]
        rows.append(BatchRow(n, elapsed, len(inputs), len(ok), sum(r.frames for r in ok)))
    return rows


def print_batch_rows(rows: Sequence[BatchRow]) -> None:
    """The table of :func:`batch_rows`, with each row's speed-up over the first."""
    print(f"{'workers':>7} {'seconds':>8} {'ok':>5} {'files/s':>8} {'frames/s':>8} {'speedup':>7}")
    for row in rows:
        print(f"{row.workers:7d} {row.seconds:8.1f} {row.ok:2d}/{row.inputs:<2d} "
              f"{row.inputs / row.seconds:8.2f} {row.frames / row.seconds:8.0f} "
              f"{rows[0].seconds / row.seconds:6.2f}x")
