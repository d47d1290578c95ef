"""A small C kernel of the solver compiled once, cached and checked as the step function.

:mod:`.native` builds the CasADi step functions; this module builds a hand-written C file (the
closed-form step, :mod:`.tree_solve`) with the same compiler, cache folder and content check,
and loads it with :mod:`ctypes`. It is a module of its own so that the step functions' build
fingerprint (:func:`.native.generator_fingerprint`, which hashes :mod:`.native`) does not change
with it: an edit here rebuilds the kernel only.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from ..atomic import atomic_path, atomic_write_text
from .native import _failure_reason, cache_dir, compiler_identity, find_compiler


def native_kernel(source: Path) -> tuple[ctypes.CDLL | None, str | None]:
    """The C file ``source`` compiled once to a shared library, cached and checked.

    The library's name holds a hash of the source, of this module and of the compiler's
    identity; it is loaded only when its content matches the SHA-256 recorded beside it when it
    was built (else rebuilt). The first build says so on stderr (one line).

    Returns:
        ``(the loaded library or None, warning or None)``: None without a C compiler or with
        ``IKFUSION_NO_COMPILE`` (no warning), or when the build failed (with a warning).
    """
    if os.environ.get("IKFUSION_NO_COMPILE"):
        return None, None
    compiler = find_compiler()
    if compiler is None:
        return None, None
    folder = cache_dir()
    try:
        build = hashlib.sha256(b"|".join([source.read_bytes(), Path(__file__).read_bytes(),
                                          compiler_identity(compiler).encode()])).hexdigest()
        library = folder / f"{source.stem}_{build[:16]}.so"
        loaded = _load_verified(library)
        if loaded is not None:
            return loaded, None
        print(f"ikfusion: compiling the solver's {source.stem} kernel once ({compiler}, cached "
              f"in {folder}) ...", file=sys.stderr, flush=True)
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        with atomic_path(library) as built:
            # -O2 as the step function (no fast-math: IEEE arithmetic, the same numbers)
            subprocess.run([compiler, "-O2", "-shared", "-fPIC", str(source), "-o", str(built),
                            "-lm"], check=True, capture_output=True, timeout=600)
            digest = hashlib.sha256(built.read_bytes()).hexdigest()
        atomic_write_text(_record(library), digest + "\n")
        loaded = _load_verified(library)
        if loaded is None:
            raise RuntimeError("the library just built does not match its own record")
        return loaded, None
    except (OSError, subprocess.SubprocessError, RuntimeError) as err:
        warning = (f"compiling the solver's {source.stem} kernel failed "
                   f"({_failure_reason(err)}); LAPACK solves the closed-form steps instead")
        print(f"ikfusion: warning: {warning}", file=sys.stderr, flush=True)
        return None, warning


def _record(library: Path) -> Path:
    """The file holding the SHA-256 of ``library``'s content, written when it was built."""
    return library.with_name(library.name + ".sha256")


def _load_verified(library: Path) -> ctypes.CDLL | None:
    """``library`` loaded when its content matches its build record, else None.

    The bytes checked are the bytes loaded (a private copy), as :mod:`.native` does.
    """
    record = _record(library)
    if not (library.is_file() and record.is_file()):
        return None
    data = library.read_bytes()
    if hashlib.sha256(data).hexdigest() != record.read_text().strip():
        print(f"ikfusion: the cached kernel {library} does not match the hash recorded when it "
              "was built; it is rebuilt, not loaded", file=sys.stderr)
        return None
    with tempfile.TemporaryDirectory(prefix="ikfusion_kernel_") as private:
        copy = Path(private) / library.name
        copy.write_bytes(data)
        return ctypes.CDLL(str(copy))
