"""``ikfusion batch``: many inputs processed in parallel on Dask, resumable, with a report.

A job kind (:class:`JobKind`) says how inputs expand, how one input becomes an output folder and
which options it takes; :data:`KIND_MODULES` lists the registered kinds (``solve``).
:func:`run_batch` runs one kind over many inputs.
"""

from .fingerprint import STAMP_NAME, fingerprint
from .kinds import KIND_MODULES, BatchInput, JobKind, JobOutput, Option, expand_paths, load_kind
from .report import REPORT_COLUMNS, REPORT_NAME, JobResult
from .runner import BatchOutcome, output_names, run_batch

__all__ = [
    "KIND_MODULES",
    "REPORT_COLUMNS",
    "REPORT_NAME",
    "STAMP_NAME",
    "BatchInput",
    "BatchOutcome",
    "JobKind",
    "JobOutput",
    "JobResult",
    "Option",
    "expand_paths",
    "fingerprint",
    "load_kind",
    "output_names",
    "run_batch",
]
