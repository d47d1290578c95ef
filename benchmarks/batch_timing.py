"""Batch throughput on 1 and 2 local Dask workers: the helper the benchmarks share.

``batch_rows`` runs :func:`ikfusion.batch.runner.run_batch` (what ``ikfusion batch`` runs) on
the same inputs once per worker count, each into a fresh temporary folder, and returns the
wall time (cluster start included), the frames solved, and the CPU time every process of the
run used (this one and the workers, once they have exited): on a machine shared with other
work the wall time of 2 workers says little, while CPU seconds that grow with the workers point
at work done twice (imports, compiles, threads fighting over cores).
"""

from __future__ import annotations

import os
import resource
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
    """One batch run: workers, wall and CPU time [s], inputs, inputs ok and frames solved."""

    workers: int
    seconds: float
    cpu_seconds: float
    inputs: int
    ok: int
    frames: int


def _cpu_seconds() -> float:
    """User + system CPU time [s] of this process and its exited (waited-for) descendants."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def batch_rows(kind: str, inputs: Sequence[str], options: Mapping[str, Any],
               workers: Sequence[int] = (1, 2)) -> list[BatchRow]:
    """Run ``batch KIND`` over ``inputs`` once per worker count (fresh output folders)."""
    rows = []
    job_kind = load_kind(kind)
    for n in workers:
        with tempfile.TemporaryDirectory() as tmp:
            start, cpu = time.perf_counter(), _cpu_seconds()
            outcome = run_batch(job_kind, list(inputs), Path(tmp) / "out", dict(options),
                                workers=n, progress=False)
            elapsed, cpu = time.perf_counter() - start, _cpu_seconds() - cpu
        ok = [r for r in outcome.results if r.status == "ok"]
        rows.append(BatchRow(n, elapsed, cpu, len(inputs), len(ok), sum(r.frames for r in ok)))
    return rows


def print_batch_rows(rows: Sequence[BatchRow]) -> None:
    """The table of :func:`batch_rows`, with each row's speed-up over the first."""
    print(f"{'workers':>7} {'seconds':>8} {'cpu s':>7} {'ok':>5} {'files/s':>8} {'frames/s':>8} "
          f"{'speedup':>7}")
    for row in rows:
        print(f"{row.workers:7d} {row.seconds:8.1f} {row.cpu_seconds:7.1f} "
              f"{row.ok:2d}/{row.inputs:<2d} {row.inputs / row.seconds:8.2f} "
              f"{row.frames / row.seconds:8.0f} "
              f"{rows[0].seconds / row.seconds:6.2f}x")
    load = os.getloadavg()[0]
    print(f"(load average {load:.1f} on {os.cpu_count()} cores: other work shares the machine)"
          if load > 0.5 * (os.cpu_count() or 1) else "")
