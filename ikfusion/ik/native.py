"""Native builds of CasADi functions: compiled once, cached on disk, checked before loading.

When a C compiler is on the machine, the solver's step functions (:mod:`.compiled`) are compiled
to a shared library cached under ``$IKFUSION_CACHE`` (default ``~/.cache/ikfusion``); CasADi's
virtual machine is the fallback (and the choice when ``IKFUSION_NO_COMPILE`` is set). The
library's name holds a hash of the generating source (:func:`generator_fingerprint`), the CasADi
version and the compiler's identity; its content hash is recorded beside it when it is built and
checked before every load (a mismatch is rebuilt, never loaded).

:class:`.bound_function.BoundFunction` evaluates a function on preallocated NumPy buffers.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from .. import rotations as numpy_rotations
from .. import rotations_casadi
from ..atomic import atomic_path, atomic_write_text
from ..paths import user_cache_dir
from .bound_function import BoundFunction as BoundFunction  # re-exported (retarget uses them)
from .bound_function import column_major as column_major


def cache_dir() -> Path:
    """Folder of compiled step functions (:func:`~ikfusion.paths.user_cache_dir`)."""
    return user_cache_dir()


def find_compiler() -> str | None:
    """The C compiler used for step functions (``cc``, ``gcc`` or ``clang``), if any."""
    return shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def compiler_identity(compiler: str) -> str:
    """The compiler's resolved path and the first line of its ``--version``."""
    try:
        done = subprocess.run([compiler, "--version"], capture_output=True, text=True,
                              timeout=30, check=False)
        version = (done.stdout or done.stderr).strip().splitlines()[:1]
    except (OSError, subprocess.SubprocessError):
        version = []
    return f"{os.path.realpath(compiler)} {' '.join(version)}"


def generator_fingerprint() -> str:
    """SHA-256 of the source that generates the step functions and builds them.

    That is :mod:`.compiled`, :mod:`.compiled_sensed`, :mod:`.compiled_points`,
    :mod:`.casadi_kinematics`, :mod:`.compiled_ranges` and :mod:`.compiled_joint_tasks` (the
    expressions), this module (the build), the CasADi rotation twin and the NumPy module holding
    their shared epsilon policy.
    """
    from . import (  # imported late: no cycle
        casadi_kinematics,
        compiled,
        compiled_joint_tasks,
        compiled_points,
        compiled_ranges,
        compiled_sensed,
    )

    digest = hashlib.sha256()
    for module in (compiled.__file__, compiled_sensed.__file__, compiled_points.__file__,
                   casadi_kinematics.__file__, compiled_ranges.__file__,
                   compiled_joint_tasks.__file__, __file__, rotations_casadi.__file__,
                   numpy_rotations.__file__):
        digest.update(Path(str(module)).read_bytes())
    return digest.hexdigest()


def library_path(folder: Path, key: str, compiler: str) -> Path:
    """Where the library of structure ``key`` built by ``compiler`` is cached.

    The name holds the structure key, a hash of the generating source, the CasADi version and
    the compiler identity, and the CasADi version in clear: a change of any of them builds a
    new library instead of loading one made from other code.
    """
    build = hashlib.sha256("|".join([generator_fingerprint(), ca.CasadiMeta.version(),
                                     compiler_identity(compiler)]).encode()).hexdigest()[:16]
    return folder / f"ik_step_{key}_{build}_{ca.CasadiMeta.version()}.so"


def _record(library: Path) -> Path:
    """The file holding the SHA-256 of ``library``'s content, written when it was built."""
    return library.with_name(library.name + ".sha256")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _load_verified(library: Path, names: Sequence[str]) -> list[ca.Function] | None:
    """The functions of a cached library whose content matches its build record, else None.

    The bytes checked are the bytes loaded: they are copied to a private temporary folder and
    loaded from there, so the cache file cannot change between the check and the load.
    """
    record = _record(library)
    if not (library.is_file() and record.is_file()):
        return None
    data = library.read_bytes()
    if _sha256(data) != record.read_text().strip():
        print(f"ikfusion: the cached step function {library} does not match the hash recorded "
              "when it was built; it is rebuilt, not loaded", file=sys.stderr)
        return None
    with tempfile.TemporaryDirectory(prefix="ikfusion_step_") as private:
        copy = Path(private) / library.name
        copy.write_bytes(data)
        return [ca.external(name, str(copy)) for name in names]


def cached_functions(key: str, names: Sequence[str]) -> list[ca.Function] | None:
    """The functions ``names`` of structure ``key`` when already built and verified, else None.

    Lets a caller skip building the CasADi graphs when their library is cached (building them
    takes longer than loading). None too without a C compiler or with ``IKFUSION_NO_COMPILE``.
    """
    if os.environ.get("IKFUSION_NO_COMPILE"):
        return None
    compiler = find_compiler()
    if compiler is None:
        return None
    try:
        return _load_verified(library_path(cache_dir(), key, compiler), names)
    except (OSError, RuntimeError):
        return None


def native_functions(functions: Sequence[ca.Function], key: str
                     ) -> tuple[list[ca.Function] | None, str | None]:
    """The functions compiled to one shared library, cached on disk and checked before loading.

    A library is loaded only when its content hash equals the one recorded when it was built
    (``<library>.sha256``); otherwise it is rebuilt. The first build says so on stderr (one
    line); a failed build says so too and is returned as a warning.

    Args:
        functions: CasADi functions to compile together.
        key: Their structure key (:func:`structure_key`).

    Returns:
        ``(functions loaded from the library or None, warning or None)``: None without a C
        compiler or with ``IKFUSION_NO_COMPILE`` set (no warning), or when the build failed
        (with a warning naming why; CasADi's virtual machine is used then).
    """
    if os.environ.get("IKFUSION_NO_COMPILE"):
        return None, None
    compiler = find_compiler()
    if compiler is None:
        return None, None
    folder = cache_dir()
    names = [f.name() for f in functions]
    try:
        library = library_path(folder, key, compiler)
        loaded = _load_verified(library, names)
        if loaded is not None:
            return loaded, None
        print(f"ikfusion: compiling the solver's step function once ({compiler}, cached in "
              f"{folder}) ...", file=sys.stderr, flush=True)
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=folder) as tmp, atomic_path(library) as built:
            source = Path(tmp) / "ik_step.c"
            generator = ca.CodeGenerator(source.name, {"with_header": False})
            for function in functions:
                generator.add(function)
            generator.generate(f"{tmp}{os.sep}")
            # -O2: evaluates about a fifth faster than -O1 with the same numbers (no fast-math),
            # for a few more seconds of the one-time build (-O3 doubles it for nothing more)
            subprocess.run([compiler, "-O2", "-shared", "-fPIC", str(source), "-o",
                            str(built), "-lm"], check=True, capture_output=True, timeout=600)
            digest = _sha256(built.read_bytes())
        atomic_write_text(_record(library), digest + "\n")
        loaded = _load_verified(library, names)
        if loaded is None:
            raise RuntimeError("the library just built does not match its own record")
        return loaded, None
    except (OSError, subprocess.SubprocessError, RuntimeError) as err:
        reason = _failure_reason(err)
        warning = (f"compiling the solver's step function failed ({reason}); CasADi's virtual "
                   "machine is used instead, several times slower")
        print(f"ikfusion: warning: {warning}", file=sys.stderr, flush=True)
        return None, warning


def _failure_reason(err: BaseException) -> str:
    """A short reason for a failed build (the compiler's first error line when it has one)."""
    if isinstance(err, subprocess.CalledProcessError):
        text = err.stderr.decode(errors="replace") if isinstance(err.stderr, bytes) \
            else str(err.stderr or "")
        lines = [line for line in text.splitlines() if line.strip()]
        return f"{Path(str(err.cmd[0])).name} exit code {err.returncode}" + (
            f": {lines[0][:200]}" if lines else "")
    return str(err)[:200] or type(err).__name__
