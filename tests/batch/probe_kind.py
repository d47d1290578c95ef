"""Toy job kinds for the batch tests, in a module of their own that workers import by name.

``IMPORTED_BY`` is the id of the process that imported this module: a worker forked from a
server that imported it already sees the server's id, a worker that imported it itself its own.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ikfusion.batch import BatchInput, JobKind, JobOutput, expand_paths

#: The process that imported this module (see the module docstring).
IMPORTED_BY = os.getpid()


def expand_text_files(inputs: Sequence[str], options: Mapping[str, Any]) -> list[BatchInput]:
    """Every file matched by INPUTS is one input."""
    return [BatchInput(str(p), p.stem, (p,), str(p.resolve())) for p in expand_paths(inputs)]


def report_process(source: str, out_dir: Path, options: Mapping[str, Any]) -> JobOutput:
    """Write which process ran the input and whether it imported this module itself."""
    (out_dir / "process.json").write_text(json.dumps(
        {"pid": os.getpid(), "imported_here": IMPORTED_BY == os.getpid()}))
    if options.get("log"):  # the order inputs were taken in, one stem a line
        with open(options["log"], "a") as log:
            log.write(Path(source).stem + "\n")
    return JobOutput(frames=1)


PROBE = JobKind("probe", "which process runs an input", "which process runs an input", (),
                expand_text_files, report_process)
