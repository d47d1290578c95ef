"""Batch throughput on 1 and 2 local Dask workers: the helper the benchmarks share.

``batch_rows`` runs :func:`ikfusion.batch.runner.run_batch` (what ``ikfusion batch`` runs) on
the same inputs once per worker count, each into a fresh temporary folder, and returns the
wall time (cluster start included), the start-up (wall time before the first input began: the
cluster, the worker processes and their imports), the frames solved, and the CPU time every
process of the run used (this one, the workers once they have exited, and the process the
workers are forked from, which outlives the run): on a machine shared with other work the wall
time of 2 workers says little, while CPU seconds that grow with the workers point at work done
twice (imports, compiles, threads fighting over cores). The table gives each row's speed-up
over the first with the start-up and without it (from the first input's start to the end: the
throughput of the running workers, which the start-up of a short benchmark batch would hide).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ikfusion.batch.kinds import load_kind
from ikfusion.batch.report import JobResult
from ikfusion.batch.runner import run_batch


@dataclasses.dataclass(frozen=True)
class BatchRow:
    """One batch run: workers, wall and CPU time [s], inputs, inputs ok and frames solved.

    ``startup_seconds`` is the wall time [s] before the first input began (cluster start).
    """

    workers: int
    seconds: float
    cpu_seconds: float
    inputs: int
    ok: int
    frames: int
    startup_seconds: float


def _cpu_seconds() -> float:
    """User + system CPU time [s] of this process and all its descendants.

    Exited (waited-for) children through ``getrusage``; children still alive (the fork server
    local workers start from) with what they and their own exited children used.
    """
    import psutil  # a dependency of Dask

    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime
    for child in psutil.Process().children():
        try:
            t = child.cpu_times()
        except psutil.Error:  # exited meanwhile: getrusage has it once it is waited for
            continue
        total += t.user + t.system + t.children_user + t.children_system
    return total


def measure_row(kind: str, inputs: Sequence[str], options: Mapping[str, Any],
                workers: int) -> BatchRow:
    """Run ``batch KIND`` over ``inputs`` on ``workers`` local workers in this process."""
    began: list[float] = []

    def first_began(result: JobResult) -> None:
        if not began:  # the first input to finish began its work this long ago
            began.append(time.perf_counter() - result.seconds)

    job_kind = load_kind(kind)
    with tempfile.TemporaryDirectory() as tmp:
        start, cpu = time.perf_counter(), _cpu_seconds()
        outcome = run_batch(job_kind, list(inputs), Path(tmp) / "out", dict(options),
                            workers=workers, progress=False, on_result=first_began)
        elapsed, cpu = time.perf_counter() - start, _cpu_seconds() - cpu
    ok = [r for r in outcome.results if r.status == "ok"]
    return BatchRow(workers, elapsed, cpu, len(inputs), len(ok), sum(r.frames for r in ok),
                    (began[0] if began else math.nan) - start)


def batch_rows(kind: str, inputs: Sequence[str], options: Mapping[str, Any],
               workers: Sequence[int] = (1, 2)) -> list[BatchRow]:
    """Run ``batch KIND`` over ``inputs`` once per worker count (fresh output folders).

    Each run is in a fresh process with the job kind imported (as ``ikfusion batch`` is once
    it has expanded its inputs), so that no run inherits the warm worker server of another.
    """
    import ikfusion

    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(Path(ikfusion.__file__).resolve().parents[1]),
                    env.get("PYTHONPATH")) if p)
    rows = []
    for n in workers:
        request = json.dumps({"kind": kind, "inputs": list(inputs), "options": dict(options),
                              "workers": n})
        done = subprocess.run([sys.executable, __file__, request], env=env, check=True,
                              capture_output=True, text=True)
        rows.append(BatchRow(**json.loads(done.stdout.strip().splitlines()[-1])))
    return rows


def _working_seconds(row: BatchRow) -> float:
    """Wall time [s] from the first input's start to the end (the cluster's start-up left out)."""
    return row.seconds - row.startup_seconds


def print_batch_rows(rows: Sequence[BatchRow]) -> None:
    """The table of :func:`batch_rows`, with each row's speed-up over the first."""
    print(f"{'workers':>7} {'seconds':>8} {'start s':>7} {'cpu s':>7} {'ok':>5} {'files/s':>8} "
          f"{'frames/s':>8} {'speedup':>7} {'after start':>11}")
    for row in rows:
        print(f"{row.workers:7d} {row.seconds:8.1f} {row.startup_seconds:7.1f} "
              f"{row.cpu_seconds:7.1f} "
              f"{row.ok:2d}/{row.inputs:<2d} {row.inputs / row.seconds:8.2f} "
              f"{row.frames / row.seconds:8.0f} "
              f"{rows[0].seconds / row.seconds:6.2f}x "
              f"{_working_seconds(rows[0]) / _working_seconds(row):10.2f}x")
    load = os.getloadavg()[0]
    print(f"(load average {load:.1f} on {os.cpu_count()} cores: other work shares the machine)"
          if load > 0.5 * (os.cpu_count() or 1) else "")


if __name__ == "__main__":  # one row, for batch_rows: the request as JSON, the row as JSON
    asked = json.loads(sys.argv[1])
    row = measure_row(asked["kind"], asked["inputs"], asked["options"], asked["workers"])
    print(json.dumps(dataclasses.asdict(row)))
