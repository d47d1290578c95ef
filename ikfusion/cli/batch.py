"""``ikfusion batch KIND INPUTS... --out DIR``: many inputs in parallel on Dask.

One subcommand per registered job kind (:data:`ikfusion.batch.KIND_MODULES`), each with the
common options (INPUTS, ``--out``, ``--workers``, ``--scheduler``, ``--quiet``) and the kind's
own. Exit 0 when every input is ok or skipped, 2 when some input is bad (the report names file,
line and field), 1 on an internal error, 130 on Ctrl-C (after writing the report).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from ..batch import KIND_MODULES, JobKind, load_kind, run_batch
from ..batch.report import counts
from . import add_force_option


def _add_kind(sub: argparse._SubParsersAction, kind: JobKind) -> None:
    """Add ``ikfusion batch <kind>`` with the common options and the kind's options."""
    p = sub.add_parser(kind.name, help=kind.help, description=kind.description)
    p.add_argument("inputs", nargs="+", metavar="INPUTS",
                   help="inputs: files, folders or globs (quote globs for ** patterns)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="batch folder: one output folder per input and batch_report.csv")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1, metavar="N",
                   help="local worker processes, one thread each (default: the CPU count)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on this Dask scheduler instead of a local cluster (the workers "
                   "must see the inputs and --out under the same paths)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_force_option(p)
    groups: dict[str, Any] = {}
    for option in kind.options:
        target: Any = p
        if option.group is not None:
            if option.group not in groups:
                groups[option.group] = p.add_mutually_exclusive_group()
            target = groups[option.group]
        target.add_argument(*option.flags, **dict(option.settings))
    p.set_defaults(func=run, batch_kind=kind.name)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``batch`` command and one subcommand per job kind."""
    p = subparsers.add_parser(
        "batch",
        help="process many inputs in parallel on Dask (resumable, with a report)",
        description="Run a job kind over many inputs on a Dask local cluster (or a scheduler "
        "given by --scheduler): one output folder per input under --out, written atomically; "
        "reruns skip inputs already done with the same files and options; "
        "DIR/batch_report.csv lists input,status,error,frames,seconds.",
    )
    sub = p.add_subparsers(dest="batch_kind", metavar="KIND")
    sub.required = True
    for name in KIND_MODULES:
        _add_kind(sub, load_kind(name))


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion batch KIND``."""
    kind = load_kind(args.batch_kind)
    options = {o.dest: getattr(args, o.dest) for o in kind.options}
    outcome = run_batch(kind, args.inputs, args.out, options, workers=args.workers,
                        scheduler=args.scheduler, progress=not args.quiet, force=args.force)
    tally = counts(outcome.results)
    for result in outcome.results:
        if result.status == "failed":
            print(f"failed: {result.input}: {result.error}", file=sys.stderr)
    print(f"batch {kind.name}: {tally['ok']} ok, {tally['skipped']} skipped, "
          f"{tally['failed']} failed; report {outcome.report}")
    return outcome.exit_code
