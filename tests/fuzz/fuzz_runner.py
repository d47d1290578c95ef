"""Run fuzz cases through the ``ikfusion`` CLI in forked workers with time and memory limits.

A worker is forked once (the imports are paid once) and runs cases one after another in
process: ``ikfusion.cli.main(argv)`` with standard output and error captured, under a
``signal.alarm`` (the case's time limit) and an address-space limit of the worker's start size
plus the memory limit. Each case's peak resident memory is measured with ``VmHWM`` after a reset
through ``/proc/self/clear_refs``. A worker that dies or stops answering is replaced and its case
recorded as a crash or a timeout, so one bad case never stops the campaign.

A case passes when it exits 0 or 2; on 2 the message names the mutated file (or the trial
folder, when a file of it was deleted or replaced by a folder) and shows no traceback; on 0 no
NaN or infinity reaches standard output or an output file (CSV, JSON, YAML, MOT, BVH, MT Manager
text, or a float array of an ``.npz``).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import multiprocessing as mp
import os
import random
import re
import resource
import shutil
import signal
import sys
import time
import traceback
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from fuzz_mutators import WHOLE_FILE, Case, draw_mutations, mutate_file
from fuzz_seeds import Seed, copy_seed

from ikfusion.cli import main
from ikfusion.errors import InputError

#: Exit 0 outputs must hold no NaN/inf value (JSON's NaN/Infinity, numpy's nan/inf).
_NON_FINITE = re.compile(r"[-+]?(nan|inf|infinity)", re.I)
_FIELD_SPLIT = re.compile(r"[\s,;=:\[\]()]+")
_OUTPUT_SUFFIXES = (".csv", ".json", ".yaml", ".mot", ".txt", ".bvh")


class CaseTimeout(BaseException):
    """Raised by the alarm inside a case (a BaseException: ``main`` must not catch it)."""


@dataclass(frozen=True)
class Outcome:
    """What one case did.

    Attributes:
        case: The case (printable, replayable).
        code: Exit code; None when it timed out or its worker died.
        seconds: Wall time of the case [s].
        peak_mb: Peak resident memory of the worker during the case [MB].
        problem: Why the case fails (None: it passes).
        last_line: The last line of standard error (or of the traceback).
    """

    case: Case
    code: int | None
    seconds: float
    peak_mb: float
    problem: str | None
    last_line: str


def draw_cases(seeds: Sequence[Seed], n: int, seed: int,
               weights: dict[str, float] | None = None) -> list[Case]:
    """``n`` cases over ``seeds``: a reader by weight, one of its seeds, then the mutations."""
    rng = random.Random(seed)
    by_reader: dict[str, list[Seed]] = defaultdict(list)
    for s in seeds:
        by_reader[s.reader].append(s)
    readers = sorted(by_reader)
    w = [(weights or {}).get(r, 1.0) for r in readers]
    cases = []
    for _ in range(n):
        reader = rng.choices(readers, weights=w)[0]
        s = rng.choice(by_reader[reader])
        cases.append(Case(reader, s.source, rng.getrandbits(31), draw_mutations(rng, s.binary)))
    return cases


def _peak_reset() -> None:
    with contextlib.suppress(OSError):
        Path("/proc/self/clear_refs").write_text("5")


def _status_mb(key: str) -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _non_finite_in(value: Any, where: str = "") -> str | None:
    """The key path of the first NaN/inf number (or "nan"/"inf" string) in parsed JSON/YAML."""
    if isinstance(value, float) and not math.isfinite(value):
        return where or "(top)"
    if isinstance(value, str) and _NON_FINITE.fullmatch(value.strip()):
        return where or "(top)"
    if isinstance(value, dict):
        items: Iterable[tuple[Any, Any]] = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return None
    for key, item in items:
        found = _non_finite_in(item, f"{where}.{key}" if where else str(key))
        if found:
            return found
    return None


def _non_finite_text(text: str, suffix: str) -> str | None:
    """Where a NaN/inf value sits in an output's text (None: nowhere).

    JSON and YAML are parsed and their numbers checked (so a warning that says "NaN" is no
    hit); tables are split into fields and a field that is exactly NaN/inf is a hit.
    """
    if suffix in (".json", ".yaml"):
        try:
            parsed = json.loads(text) if suffix == ".json" else yaml.safe_load(text)
        except (ValueError, yaml.YAMLError):
            parsed = None
        if parsed is not None:
            found = _non_finite_in(parsed)
            return None if found is None else f"at {found}"
    for n, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith(("//", "#")):
            continue
        for field in _FIELD_SPLIT.split(line):
            if _NON_FINITE.fullmatch(field.strip("\"'")):
                return f"line {n}: {line.strip()[:80]!r}"
    return None


def _non_finite_outputs(stdout: str, out: Path) -> str | None:
    """Where a NaN/inf value reached an output (None: nowhere)."""
    stripped = stdout.strip()
    found = _non_finite_text(stdout, ".json" if stripped.startswith(("{", "[")) else ".txt")
    if found:
        return f"non-finite value in standard output {found}"
    if not out.is_dir():
        return None
    for f in sorted(out.rglob("*")):
        if f.suffix in _OUTPUT_SUFFIXES and f.is_file():
            found = _non_finite_text(f.read_text(errors="replace"), f.suffix)
            if found:
                return f"non-finite value in {f.name} {found}"
        if f.suffix == ".npz" and f.is_file():
            with np.load(f, allow_pickle=False) as npz:
                for key in npz.files:
                    a = npz[key]
                    if a.dtype.kind in "fc" and not np.isfinite(a).all():
                        return f"non-finite value in {f.name}[{key}]"
    return None


def _call_reader(command: str, func: Any, path: Path) -> int:
    """A reader function with the exceptions mapped exactly as ``ikfusion.cli.main`` does."""
    try:
        func(path)
    except InputError as err:
        print(f"ikfusion {command}: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 - as main: exit 1 with the traceback
        traceback.print_exc()
        print(f"ikfusion {command}: internal error: {err}", file=sys.stderr)
        return 1
    return 0


def _innermost(err: BaseException) -> str:
    """``file:line function`` of the innermost ikfusion frame where ``err`` was raised."""
    frames = traceback.extract_tb(err.__traceback__)
    ours = [f for f in frames if "/ikfusion/" in f.filename and "/tests/" not in f.filename]
    ours = ours or frames
    f = ours[-1]
    return f"{f.filename.split('/ikfusion/')[-1]}:{f.lineno} {f.name}"


def run_case(case: Case, seed: Seed, workdir: Path, timeout: float,
             memory_mb: float = float("inf"), keep: bool = False) -> tuple[Outcome, str, str]:
    """Run one case in this process; returns the outcome, standard output and error."""
    case_dir = workdir / f"case{case.seed}"
    shutil.rmtree(case_dir, ignore_errors=True)
    target = copy_seed(seed, case_dir / "in")
    mutate_file(target, case.mutations, case.seed)
    out = case_dir / "out"
    out.mkdir()
    values = {"dir": str(target.parent), "file": str(target), "out": str(out)}
    stdout, stderr = io.StringIO(), io.StringIO()

    def alarm(signum: int, frame: object) -> None:
        raise CaseTimeout

    previous = signal.signal(signal.SIGALRM, alarm)
    _peak_reset()
    start = time.perf_counter()
    code: int | None
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            signal.setitimer(signal.ITIMER_REAL, timeout)
            try:
                if seed.call is not None:
                    code = _call_reader(seed.call[0], seed.call[1], target)
                else:
                    code = int(main([a.format(**values) for a in seed.argv]))
            except SystemExit as err:  # argparse usage errors
                code = err.code if isinstance(err.code, int) else 1
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
    except CaseTimeout as err:
        code = None
        print(f"timed out in {_innermost(err)}", file=stderr)
    finally:
        signal.signal(signal.SIGALRM, previous)
    seconds = time.perf_counter() - start
    peak = _status_mb("VmHWM")
    err_text = stderr.getvalue()
    names = [target.name]
    if case.mutations[0] in WHOLE_FILE and any("{dir}" in a for a in seed.argv):
        names.append(str(target.parent))  # a file gone from a trial: naming the trial will do
    problem = judge(code, seconds, timeout, err_text, stdout.getvalue(), out, names, peak,
                    memory_mb)
    lines = [ln for ln in err_text.strip().splitlines() if ln.strip()]
    last = lines[-1] if lines else ""
    if not keep:
        shutil.rmtree(case_dir, ignore_errors=True)
    return Outcome(case, code, seconds, peak, problem, last), stdout.getvalue(), err_text


def judge(code: int | None, seconds: float, timeout: float, stderr: str, stdout: str,
          out: Path, names: Sequence[str], peak_mb: float = 0.0,
          memory_mb: float = float("inf")) -> str | None:
    """Why a case fails, or None when it passes (see the module docstring)."""
    if code is None or seconds > timeout:
        return f"timeout after {seconds:.1f} s"
    if peak_mb > memory_mb:
        return f"peak memory {peak_mb:.0f} MB"
    if code not in (0, 2):
        return f"exit {code}"
    if code == 2:
        if "Traceback" in stderr:
            return "exit 2 with a traceback"
        if not any(name in stderr for name in names):
            return "exit 2 without naming the mutated file"
        return None
    return _non_finite_outputs(stdout, out)


def limit_memory(memory_mb: float) -> None:
    """Cap this process's address space at its present size plus ``memory_mb`` [MB].

    An allocation beyond it raises ``MemoryError`` (exit 1 through ``main``), so a runaway case
    fails fast instead of swapping the machine.
    """
    limit = int((_status_mb("VmSize") + memory_mb) * 1024 * 1024)
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))


def _worker(conn: Connection, seeds: dict[tuple[str, str], Seed], workdir: Path,
            timeout: float, memory_mb: float) -> None:
    """Run the cases sent on ``conn`` until it closes; answer each with its outcome."""
    limit_memory(memory_mb)
    workdir.mkdir(parents=True, exist_ok=True)
    while True:
        try:
            text = conn.recv()
        except EOFError:
            break
        if text is None:
            break
        case = Case.parse(text)
        try:
            outcome, _, _ = run_case(case, seeds[case.reader, case.source], workdir, timeout,
                                     memory_mb)
        except BaseException as err:  # noqa: BLE001 - a harness failure is reported, not lost
            outcome = Outcome(case, 1, 0.0, 0.0, f"harness error {type(err).__name__}",
                              str(err).splitlines()[-1] if str(err) else "")
        conn.send(outcome)
    os._exit(0)


class Campaign:
    """Forked workers that run cases with a time and a memory limit each."""

    def __init__(self, seeds: Iterable[Seed], workdir: Path, workers: int = 1,
                 timeout: float = 30.0, memory_mb: float = 2048.0) -> None:
        self.seeds = {(s.reader, s.source): s for s in seeds}
        self.workdir = workdir
        self.timeout = timeout
        self.memory_mb = memory_mb
        self.n_workers = max(1, workers)

    def _start(self, k: int) -> tuple[Any, Connection]:
        ctx = mp.get_context("fork")
        here, there = ctx.Pipe()
        proc = ctx.Process(target=_worker, daemon=True, args=(
            there, self.seeds, self.workdir / f"w{k}", self.timeout, self.memory_mb))
        proc.start()
        there.close()
        return proc, here

    def run(self, cases: Sequence[Case]) -> list[Outcome]:
        """Every case's outcome, in the order given."""
        pending = list(enumerate(cases))[::-1]
        results: dict[int, Outcome] = {}
        workers = [self._start(k) for k in range(min(self.n_workers, len(cases)))]
        busy: dict[int, tuple[int, float]] = {}  # worker -> (case index, start time)
        try:
            while pending or busy:
                for k in range(len(workers)):
                    if k not in busy and pending:
                        i, case = pending.pop()
                        workers[k][1].send(str(case))
                        busy[k] = (i, time.monotonic())
                ready = wait([workers[k][1] for k in busy], timeout=1.0)
                for k in list(busy):
                    proc, conn = workers[k]
                    i, t0 = busy[k]
                    elapsed = time.monotonic() - t0
                    if conn in ready:
                        try:
                            results[i] = conn.recv()
                            del busy[k]
                            continue
                        except EOFError:
                            proc.join(5)
                            problem = f"worker died (exit {proc.exitcode})"
                    elif elapsed > self.timeout + 15:
                        problem = f"timeout after {elapsed:.1f} s (worker killed)"
                    else:
                        continue
                    results[i] = Outcome(cases[i], None, elapsed, float("nan"), problem, "")
                    del busy[k]
                    proc.kill()
                    proc.join(5)
                    workers[k] = self._start(k)
        finally:
            for proc, conn in workers:
                with contextlib.suppress(OSError):
                    conn.send(None)
                conn.close()
                proc.join(10)
                if proc.is_alive():
                    proc.kill()
        return [results[i] for i in range(len(cases))]


def normalise(line: str) -> str:
    """An error line with paths and numbers blanked, to group failures by cause."""
    line = re.sub(r"(/[^\s:,'\"]+)+", "<path>", line)
    line = re.sub(r"\b0x[0-9a-f]+\b", "<hex>", line)
    line = re.sub(r"invalid (start|continuation) byte", "invalid byte", line)
    return re.sub(r"\d+(\.\d+)?", "N", line)[:160]


#: Likely causes of failures, recognised from the problem and the last error line.
CAUSES: tuple[tuple[str, str], ...] = (
    (r"codec can't decode|UnicodeDecodeError|UnicodeError",
     "text read as strict UTF-8 (Latin-1, UTF-16 or binary bytes raise UnicodeDecodeError)"),
    (r"zip|CRC|magic number|No data left|npy|pickle|EOFError|Cannot load file",
     "npz/zip/numpy load errors not mapped to InputError"),
    (r"timeout|peak memory|Unable to allocate|MemoryError|worker died",
     "runaway time or memory (or a crashed worker)"),
    (r"without naming", "exit 2 whose message does not name the mutated file"),
    (r"traceback", "exit 2 printed with a traceback"),
    (r"non-finite", "NaN or inf reaches an output"),
)


def likely_cause(outcome: Outcome) -> str:
    """A short name of the likely cause of a failing case."""
    text = f"{outcome.problem} {outcome.last_line}"
    for pattern, cause in CAUSES:
        if re.search(pattern, text, re.I):
            return cause
    return "other internal error (exit 1)"


def catalogue(outcomes: Sequence[Outcome], replay: str) -> str:
    """Failing cases grouped by likely cause, reader, problem and error line.

    Each group gives its count, the mutations its cases had, the error's last line and one
    replay command.
    """
    groups: dict[tuple[str, str, str, str], list[Outcome]] = defaultdict(list)
    for o in outcomes:
        if o.problem is not None:
            key = (likely_cause(o), o.case.reader,
                   o.problem.split(" (")[0].split(" after")[0].split(": ...")[0],
                   normalise(o.last_line))
            groups[key].append(o)
    if not groups:
        return "no failing case"
    lines = [f"{sum(len(g) for g in groups.values())} failing case(s) of {len(outcomes)} in "
             f"{len(groups)} group(s)"]
    cause_count: dict[str, int] = defaultdict(int)
    for key, group in groups.items():
        cause_count[key[0]] += len(group)
    order = sorted(groups.items(), key=lambda kv: (-cause_count[kv[0][0]], kv[0][0], -len(kv[1])))
    cause = None
    for (group_cause, reader, problem, _), group in order:
        if group_cause != cause:
            cause = group_cause
            lines.append(f"== {cause}: {cause_count[cause]} case(s)")
        muts: dict[str, int] = defaultdict(int)
        for o in group:
            for m in set(o.case.mutations):
                muts[m] += 1
        top = ", ".join(f"{m} {n}" for m, n in sorted(muts.items(), key=lambda kv: -kv[1])[:6])
        lines.append(f"- [{reader}] {problem} x{len(group)} (mutations: {top})")
        if group[0].problem != problem:
            lines.append(f"    first: {group[0].problem}"[:240])
        lines += [f"    last line: {group[0].last_line[:200]}",
                  f"    replay: {replay} '{group[0].case}'"]
    return "\n".join(lines)


def table(outcomes: Sequence[Outcome]) -> str:
    """Per reader and mutation: cases, exits 0/2, failures, exit 1, timeouts, seconds, MB.

    A case with several mutations counts once under each of them.
    """
    rows: dict[tuple[str, str], list[Outcome]] = defaultdict(list)
    for o in outcomes:
        for m in sorted(set(o.case.mutations)):
            rows[o.case.reader, m].append(o)
        rows[o.case.reader, "(all)"].append(o)
    head = ("reader", "mutation", "cases", "exit0", "exit2", "fail", "exit1", "timeout",
            "mean_s", "max_s", "max_MB")
    body = []
    for (reader, m), group in sorted(rows.items()):
        peaks = [o.peak_mb for o in group if o.peak_mb == o.peak_mb]
        body.append((reader, m, str(len(group)),
                     str(sum(o.code == 0 for o in group)), str(sum(o.code == 2 for o in group)),
                     str(sum(o.problem is not None for o in group)),
                     str(sum(o.code == 1 for o in group)),
                     str(sum(o.problem is not None and o.problem.startswith("timeout")
                             for o in group)),
                     f"{sum(o.seconds for o in group) / len(group):.3f}",
                     f"{max(o.seconds for o in group):.2f}", f"{max(peaks, default=0):.0f}"))
    widths = [max(len(r[k]) for r in [head, *body]) for k in range(len(head))]
    return "\n".join("  ".join(v.ljust(w) if k < 2 else v.rjust(w)
                               for k, (v, w) in enumerate(zip(r, widths))) for r in [head, *body])


def exit2_messages(outcomes: Sequence[Outcome], top: int = 5) -> str:
    """The most frequent exit-2 messages per reader (paths and numbers blanked)."""
    counts: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for o in outcomes:
        if o.code == 2:
            counts[o.case.reader][normalise(o.last_line.split(": error: ", 1)[-1])] += 1
    lines = []
    for reader in sorted(counts):
        lines.append(f"{reader}:")
        ranked = sorted(counts[reader].items(), key=lambda kv: -kv[1])[:top]
        lines += [f"  {n:4d}  {msg}" for msg, n in ranked]
    return "\n".join(lines)
