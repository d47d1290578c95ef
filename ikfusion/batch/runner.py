"""Run a batch on Dask: one output folder per input, resumable, interruptible.

The client (this process) expands the inputs, names their output folders, skips those already
finished with the same fingerprint and submits the rest, one Dask task each and the largest
inputs first, to a ``LocalCluster`` (N worker processes, one thread each, forked from a server
that imported the job kind once: :mod:`.workers`) or to a running scheduler. A task writes
into a partial folder that is renamed on success (:func:`ikfusion.atomic.atomic_folder`),
so an output folder is whole or absent. On Ctrl-C the pending tasks are cancelled, the cluster
is closed, partial folders are removed and the report lists what finished.

The workers must see the inputs and the output folder under the same paths (one machine, or a
shared file system). One batch at a time per output folder.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import re
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..atomic import atomic_folder
from ..atomic import remove_leftovers as remove_atomic_leftovers
from ..errors import InputError
from ..output_folders import check_output_folder, prepare_output_folder
from .fingerprint import fingerprint, is_complete, read_stamp, write_stamp
from .kinds import BatchInput, JobKind, JobOutput, RunFn
from .report import REPORT_NAME, JobResult, exit_code, write_report
from .workers import warm_workers


@dataclass(frozen=True)
class PlannedJob:
    """One input with its output folder and fingerprint."""

    item: BatchInput
    name: str
    fingerprint: str


@dataclass(frozen=True)
class BatchOutcome:
    """The results of a batch run, in input order, and where its report is."""

    results: list[JobResult]
    report: Path
    interrupted: bool = False

    @property
    def exit_code(self) -> int:
        """0 all ok or skipped, 2 some bad input, 1 some internal error."""
        return exit_code(self.results)


def _safe(text: str) -> str:
    """A folder-name-safe version of ``text`` (no separators, not hidden)."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._-")
    return cleaned or "input"


def output_names(items: Sequence[BatchInput]) -> list[str]:
    """Unique output folder names: the stem, prefixed by parent folders until names differ.

    ``a/imu/SIM_`` and ``b/imu/SIM_`` become ``a-imu-SIM`` and ``b-imu-SIM``; inputs that still
    collide get a short hash of their absolute path.
    """
    parents = [[_safe(p.name) for p in Path(it.label).resolve().parents if p.name]
               for it in items]
    stems = [_safe(it.stem) for it in items]
    depth = [len(p) for p in parents]

    def name(i: int) -> str:
        return "-".join([*reversed(parents[i][:depth[i]]), stems[i]])

    def clashing() -> set[int]:
        groups: dict[str, list[int]] = {}
        for i in range(len(items)):
            groups.setdefault(name(i), []).append(i)
        return {i for g in groups.values() if len(g) > 1 for i in g}

    hopeless = clashing()  # same folder and stem: parents cannot tell them apart
    depth = [0] * len(items)
    while True:
        growable = [i for i in clashing() - hopeless if depth[i] < len(parents[i])]
        if not growable:
            break
        for i in growable:
            depth[i] += 1
    names = [name(i) for i in range(len(items))]
    seen: dict[str, int] = {}
    for n in names:
        seen[n] = seen.get(n, 0) + 1
    for i, n in enumerate(names):
        if seen[n] > 1:
            tag = hashlib.sha1(str(Path(items[i].label).resolve()).encode()).hexdigest()[:8]
            names[i] = f"{n}-{tag}"
    return names


def remove_leftovers(out_dir: Path) -> list[Path]:
    """Remove the partial folders a killed or interrupted run left in ``out_dir``; return them.

    One batch at a time per output folder: every leftover is removed, whatever its process.
    """
    return remove_atomic_leftovers(out_dir, only_dead=False)


def plan_jobs(kind: JobKind, items: Sequence[BatchInput], options: Mapping[str, Any],
              version: str) -> list[PlannedJob]:
    """Name every input's output folder and fingerprint it."""
    names = output_names(items)
    return [PlannedJob(it, n, fingerprint(kind.name, version, options, it.files))
            for it, n in zip(items, names)]


def _frames_in(folder: Path) -> int:
    """Frames of a finished output, from its ``batch.json`` (0 when unknown)."""
    stamp = read_stamp(folder) or {}
    try:
        return int(stamp.get("frames", 0))
    except (TypeError, ValueError):
        return 0


def _frames_from_summary(folder: Path) -> int:
    """Frames from ``summary.json`` when a kind's ``run`` returned nothing."""
    import json

    try:
        return int(json.loads((folder / "summary.json").read_text()).get("frames", 0))
    except (OSError, ValueError, TypeError, AttributeError):
        return 0


def _as_output(value: JobOutput | int | None, folder: Path) -> JobOutput:
    """Normalise what a kind's ``run`` returned."""
    if isinstance(value, JobOutput):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return JobOutput(frames=value)
    return JobOutput(frames=_frames_from_summary(folder))


def process_input(run: RunFn, kind_name: str, job: PlannedJob, out_dir: str,
                  options: Mapping[str, Any], version: str, force: bool = False) -> JobResult:
    """Process one input into ``out_dir/job.name`` with ``run`` (on a Dask worker).

    The output is written in a partial folder renamed on success, with ``batch.json``. Errors
    become a failed :class:`JobResult` (bad input or internal), never an exception, so one bad
    input does not stop the batch. An existing folder is replaced only when ikfusion wrote it,
    or with ``force``.
    """
    final = Path(out_dir) / job.name
    start = time.perf_counter()
    try:
        with atomic_folder(final, f"batch {kind_name}", force) as partial:
            output = _as_output(run(job.item.source, partial, options), partial)
            seconds = time.perf_counter() - start
            write_stamp(partial, {
                "kind": kind_name, "input": job.item.label, "fingerprint": job.fingerprint,
                "ikfusion_version": version, "options": dict(options),
                "files": [str(p) for p in job.item.files], "frames": output.frames,
                "seconds": round(seconds, 3), "warnings": list(output.warnings),
                "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            })
    except InputError as err:
        return JobResult(job.item.label, job.name, "failed", str(err), 0,
                         time.perf_counter() - start, bad_input=True)
    except Exception as err:  # noqa: BLE001 - reported in batch_report.csv, exit code 1
        return JobResult(job.item.label, job.name, "failed", f"{type(err).__name__}: {err}", 0,
                         time.perf_counter() - start)
    return JobResult(job.item.label, job.name, "ok", "", output.frames, seconds)


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT while worker processes start, so that they inherit ignoring it.

    A terminal's Ctrl-C goes to every process of the foreground group: without this, each
    local worker would die with its own traceback instead of being stopped by the client.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def dask_client(workers: int, scheduler: str | None,
                preload: Sequence[str] = ()) -> Iterator[Any]:
    """A Dask client: on ``scheduler`` when given, else on a local cluster of ``workers``.

    The local cluster has one single-threaded worker process per ``workers``, forked from a
    server that imported ``preload`` once (:func:`.workers.warm_workers`), listens on the
    loopback interface only and has no dashboard. Closing it stops the workers (and their tasks).
    """
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler}: {err}; start "
                             "one with `dask scheduler` or leave --scheduler out for a local "
                             "cluster", field="scheduler") from None
        try:
            yield client
        finally:
            client.close()
        return
    if workers < 1:
        raise InputError(f"--workers must be at least 1, not {workers}", field="workers")
    # The workers' own log stays quiet: a task's error comes back with its future (and goes
    # into batch_report.csv), a worker that dies is reported by the runner, and what is left
    # are connection errors while the cluster stops, which say nothing to a user.
    with warm_workers(preload):
        with _sigint_ignored():  # Ctrl-C reaches the client only; it stops the workers itself
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=":0",  # any free port
                                   silence_logs=logging.CRITICAL)
        try:
            client = Client(cluster)
            try:
                yield client
            except KeyboardInterrupt:
                # the workers' connections break while the cluster stops: expected, not news
                logging.getLogger("distributed").setLevel(logging.CRITICAL)
                raise
            finally:
                client.close()
        finally:
            cluster.close()


class _Progress:
    """Progress bar: inputs done, frames per second, time left (tqdm)."""

    def __init__(self, total: int, done: int, enabled: bool) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=total, initial=done, unit="input", disable=not enabled,
                        dynamic_ncols=True)
        self.start = time.perf_counter()
        self.frames = 0

    def update(self, result: JobResult) -> None:
        """Count one finished input."""
        self.frames += result.frames if result.status == "ok" else 0
        elapsed = max(time.perf_counter() - self.start, 1e-9)
        self.bar.set_postfix_str(f"{self.frames / elapsed:.0f} frames/s", refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        """Leave the final state on screen."""
        self.bar.close()


def _skipped(job: PlannedJob, out_dir: Path) -> JobResult:
    """The result of an input already finished with the same fingerprint."""
    return JobResult(job.item.label, job.name, "skipped", "", _frames_in(out_dir / job.name))


def _finished_unseen(job: PlannedJob, out_dir: Path) -> JobResult:
    """An input a worker finished after an interrupt, before the cluster stopped."""
    stamp = read_stamp(out_dir / job.name) or {}
    return JobResult(job.item.label, job.name, "ok", "", _frames_in(out_dir / job.name),
                     float(stamp.get("seconds", 0.0)))


def input_bytes(job: PlannedJob) -> int:
    """The size of an input's files [bytes] (0 for those that are gone): its work, roughly."""
    total = 0
    for path in job.item.files:
        with contextlib.suppress(OSError):
            total += path.stat().st_size
    return total


def largest_first(jobs: Sequence[PlannedJob]) -> list[PlannedJob]:
    """``jobs`` ordered by the size of their files, largest first (ties keep their order).

    Started first, the longest inputs do not finish alone at the end while the other workers
    idle; the small ones fill the gaps.
    """
    return sorted(jobs, key=lambda job: -input_bytes(job))


def _run_on_dask(client: Any, kind: JobKind, jobs: Sequence[PlannedJob], out_dir: Path,
                 options: Mapping[str, Any], version: str, progress: _Progress,
                 done: dict[str, JobResult],
                 on_result: Callable[[JobResult], None] | None, force: bool = False) -> None:
    """Submit ``jobs`` (largest first) and collect results into ``done`` (keyed by name).

    On KeyboardInterrupt the pending futures are cancelled before it propagates.
    """
    from distributed import as_completed

    order = largest_first(jobs)
    futures = [client.submit(process_input, kind.run, kind.name, job, str(out_dir), dict(options),
                             version, force,
                             key=f"ikfusion-batch-{job.name}-{job.fingerprint[:16]}",
                             pure=False, priority=len(order) - rank)
               for rank, job in enumerate(order)]
    by_key = {f.key: job for f, job in zip(futures, order)}
    try:
        for future in as_completed(futures):
            job = by_key[future.key]
            try:
                result = future.result()
            except Exception as err:  # noqa: BLE001 - a worker died: report, go on
                result = JobResult(job.item.label, job.name, "failed",
                                   f"{type(err).__name__}: {err}")
            done[job.name] = result
            progress.update(result)
            if on_result is not None:
                on_result(result)
    except BaseException:
        client.cancel(futures, force=True)
        raise


def _inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` is ``folder`` or under it (a glob that also matched the outputs)."""
    resolved = path.resolve()
    return resolved == folder or folder in resolved.parents


def run_batch(kind: JobKind, inputs: Sequence[str], out_dir: str | Path,
              options: Mapping[str, Any], workers: int = 1, scheduler: str | None = None,
              progress: bool = True,
              on_result: Callable[[JobResult], None] | None = None,
              force: bool = False) -> BatchOutcome:
    """Process every input of ``inputs`` with ``kind`` into ``out_dir``, in parallel on Dask.

    Args:
        kind: The job kind.
        inputs: Paths and globs, as on the command line.
        out_dir: The batch output folder (one folder per input, ``batch_report.csv``).
        options: The kind's options (JSON-serialisable; they enter the fingerprint).
        workers: Local worker processes (when no ``scheduler``).
        scheduler: A Dask scheduler address, ``tcp://HOST:PORT``.
        progress: Show a progress bar on standard error.
        on_result: Called in this process with every finished input's result.
        force: Use ``out_dir`` and replace folders in it even when ikfusion did not write them.

    Returns:
        The results in input order. On KeyboardInterrupt (or the SIGTERM the command line turns
        into one) the report of what finished is written, partial folders are removed, and the
        interrupt propagates.

    Raises:
        InputError: INPUTS or options that cannot work, or a refused output folder (before
            anything runs).
    """
    from .. import __version__

    out = Path(out_dir).resolve()
    items = [it for it in kind.expand(inputs, options) if not _inside(Path(it.label), out)]
    if not items:
        raise InputError("no inputs to process", field="INPUTS")
    check_output_folder(out, force)
    jobs = plan_jobs(kind, items, options, __version__)
    for job in jobs:
        check_output_folder(out / job.name, force)
    prepare_output_folder(out, f"batch {kind.name}", force)
    remove_leftovers(out)
    outputs = kind.outputs(options)
    done: dict[str, JobResult] = {}
    todo = []
    for job in jobs:
        if is_complete(out / job.name, job.fingerprint, outputs):
            done[job.name] = _skipped(job, out)
        else:
            todo.append(job)
    bar = _Progress(len(jobs), len(done), progress)
    interrupted: KeyboardInterrupt | None = None
    try:
        if todo:
            with dask_client(workers, scheduler, [kind.run.__module__]) as client:
                _run_on_dask(client, kind, todo, out, options, __version__, bar, done,
                             on_result, force)
    except KeyboardInterrupt as stop:  # Ctrl-C, or SIGTERM as the command line raises it
        interrupted = stop
    finally:
        bar.close()
        remove_leftovers(out)
        for job in jobs:
            if job.name not in done and is_complete(out / job.name, job.fingerprint, outputs):
                done[job.name] = _finished_unseen(job, out)
        results = [done[j.name] for j in jobs if j.name in done]
        report = write_report(out / REPORT_NAME, results)
    if interrupted is not None:
        raise interrupted
    return BatchOutcome(results, report)
