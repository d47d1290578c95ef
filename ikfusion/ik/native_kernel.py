"""A small C kernel of the solver compiled once, cached and checked as the step function.

:mod:`.native` builds the CasADi step functions; this module builds a hand-written C file (the
closed-form step, :mod:`.tree_solve`) the same way (:mod:`.native_build`: the same compiler,
cache folder, announcement and content check) and loads it with :mod:`ctypes`. It is a module
of its own so that the step functions' build fingerprint (:func:`.native.generator_fingerprint`,
which hashes :mod:`.native`) does not change with it: an edit here rebuilds the kernel only.
"""

from __future__ import annotations

import ctypes
import hashlib
from pathlib import Path

from . import native_build
from .native_build import compile_shared, compiler_identity

#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "LAPACK solves the closed-form steps instead"


def kernel_path(source: Path, folder: Path, compiler: str) -> Path:
    """Where the library of the C file ``source`` built by ``compiler`` is cached.

    The name holds a hash of the source, of this module and :mod:`.native_build` (the build)
    and of the compiler's identity: a change of any of them builds a new library.
    """
    build = hashlib.sha256(b"|".join([
        source.read_bytes(), Path(__file__).read_bytes(),
        Path(native_build.__file__).read_bytes(),
        compiler_identity(compiler).encode()])).hexdigest()
    return folder / f"{source.stem}_{build[:16]}.so"


def native_kernel(source: Path, fallback: str = FALLBACK) -> tuple[ctypes.CDLL | None, str | None]:
    """The C file ``source`` compiled once to a shared library, cached and checked.

    The library (:func:`kernel_path`) is loaded only when its content matches the SHA-256
    recorded beside it when it was built (else rebuilt). The first build says so on stderr (one
    line). ``fallback``: what is used instead (the end of the warning).

    Returns:
        ``(the loaded library or None, warning or None)``: None without a C compiler or with
        ``IKFUSION_NO_COMPILE`` (no warning), or when the build failed (with a warning).
    """
    return native_build.native_library(native_build.NativeLibrary(
        what=f"{source.stem} kernel", fallback=fallback,
        path=lambda folder, compiler: kernel_path(source, folder, compiler),
        build=lambda compiler, output: compile_shared(compiler, source, output),
        load=lambda copy: ctypes.CDLL(str(copy))))
