"""How the local workers of ``ikfusion batch`` start: warm, from one server that imported once.

A worker process that starts from nothing (``spawn``) pays for a new interpreter, for importing
Dask and for importing the job kind (NumPy, Pinocchio, CasADi, ikfusion): about 1.3 CPU seconds
each, before its first input. Where the platform has it (Linux, macOS) the workers are instead
forked from a ``forkserver`` process that imported Dask, the job kind's module and the main script
once: a second worker then costs little more than a fork, and the imports are shared memory. On
other platforms (Windows) workers are spawned as before.

The Dask nanny sets ``OMP_NUM_THREADS`` / ``OPENBLAS_NUM_THREADS`` / ``MKL_NUM_THREADS`` to 1
before the first worker starts, so the server (and every worker forked from it) runs one BLAS
thread: single-threaded workers do not fight over the cores.

Dask's housekeeping is made quieter too (:data:`QUIET_SETTINGS`): by default every worker
samples its running task's stack every 10 ms for the dashboard's profile, and the scheduler,
the nannies and the workers poll their event loops every 20 ms and their memory every 100 ms.
An idle local cluster of two workers used about 0.11 CPU seconds per second of wall time that
way, 0.02 with these settings (measured on the 2-core development machine).
"""

from __future__ import annotations

import contextlib
import multiprocessing
from collections.abc import Iterator, Sequence

#: The start method of local workers where the platform offers it.
WARM_METHOD = "forkserver"

#: Dask settings of a local batch cluster: no statistical profiler (no dashboard shows it),
#: event-loop health and system and memory monitors polled every second or two, not 50 or 10
#: times a second.
QUIET_SETTINGS: dict[str, object] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def start_method() -> str:
    """``forkserver`` where the platform has it, else ``spawn``."""
    return WARM_METHOD if WARM_METHOD in multiprocessing.get_all_start_methods() else "spawn"


@contextlib.contextmanager
def warm_workers(modules: Sequence[str]) -> Iterator[str]:
    """Start the local Dask workers of this block warm; yields the start method used.

    They are forked from a server that imported ``modules`` once, and run with
    :data:`QUIET_SETTINGS`. The server is started with the first worker and lives as long as
    this process: a later batch in the same process forks from it again (its imports are those
    of the first call). A module that fails to import in the server is simply imported by each
    worker when its task needs it.

    Args:
        modules: Module names to import in the server, e.g. the job kind's module.
    """
    import dask
    from distributed.utils import get_mp_context

    method = start_method()
    settings = {**QUIET_SETTINGS, "distributed.worker.multiprocessing-method": method}
    with dask.config.set(settings):
        if method == WARM_METHOD:
            get_mp_context()  # Dask sets its own preload list once, at its first call
            # "__main__": the main script is imported once in the server, not in every worker
            multiprocessing.get_context(WARM_METHOD).set_forkserver_preload(
                ["__main__", "distributed", *modules])
        yield method
