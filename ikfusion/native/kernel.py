"""A hand-written C kernel compiled once, cached and checked as the solver's step function.

:mod:`ikfusion.ik.native` builds the CasADi step functions; this module builds a hand-written C
file beside the module that uses it (the solver's closed-form step :mod:`ikfusion.ik.tree_solve`,
its QP rows, projection and soft wall; the result writer's digits, joint-angle continuity,
placements and quaternions) the same way (:mod:`.build`: the same compiler, cache folder,
announcement and content check) and loads it with :mod:`ctypes`. It is a module of its own so
that the step functions' build fingerprint (which hashes :mod:`ikfusion.ik.native`) does not
change with it: an edit here rebuilds the kernels only. Every kernel has a NumPy (or LAPACK)
path that its caller runs without a compiler, with ``IKFUSION_NO_COMPILE`` or after a failed
build (then with a warning, :func:`kernel_warnings`).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..paths import module_source
from . import build as native_build
from .build import cache_dir, compile_shared, compiler_identity, find_compiler

#: What is used when a kernel cannot be compiled (the end of the warning), unless said.
FALLBACK = "NumPy computes instead"

#: (C file, cache folder, compiler, IKFUSION_NO_COMPILE) -> the kernel loaded (None: not built)
_LOADED: dict[tuple[str, str, str | None, str | None], ctypes.CDLL | None] = {}
_WARNINGS: list[str] = []
#: (C file, function, IKFUSION_NO_COMPILE) -> the function (None: without the kernel)
_FUNCTIONS: dict[tuple[str, str, str | None], Callable[..., int] | None] = {}


def kernel_source(module: str, file: str) -> Path:
    """The C ``file`` shipped beside the module ``module`` (its ``__name__``).

    Found from the module's source (:func:`ikfusion.paths.module_source`), not its ``__file__``:
    a module compiled by mypyc is loaded from the cache folder, without its C files.
    """
    return module_source(module).with_name(file)


def kernel_path(source: Path, folder: Path, compiler: str) -> Path:
    """Where the library of the C file ``source`` built by ``compiler`` is cached.

    The name holds a hash of the source, of this module and :mod:`.build` (the build)
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
        what=f"native {source.stem} kernel", fallback=fallback,
        path=lambda folder, compiler: kernel_path(source, folder, compiler),
        build=lambda compiler, output: compile_shared(compiler, source, output),
        load=lambda copy: ctypes.CDLL(str(copy))))


def loaded_kernel(source: Path, fallback: str = FALLBACK) -> ctypes.CDLL | None:
    """:func:`native_kernel` of ``source``, once per process and setting.

    A failed build is not retried in the same process; its warning is kept
    (:func:`kernel_warnings`). None without the kernel (no compiler, ``IKFUSION_NO_COMPILE``
    or a failed build): the caller's fallback is used.
    """
    key = (str(source), str(cache_dir()), find_compiler(), os.environ.get("IKFUSION_NO_COMPILE"))
    if key not in _LOADED:
        library, warning = native_kernel(source, fallback)
        _LOADED[key] = library
        if warning is not None:
            _WARNINGS.append(warning)
    return _LOADED[key]


def c_function(source: Path, name: str, fallback: str) -> Callable[..., int] | None:
    """The function ``name`` of the C file ``source``, taking one pointer, returning int64.

    For kernels whose functions take one pointer to a struct of their arguments (one cheap
    ctypes call). Looked up once per process and setting; ``fallback``: what is used without
    the kernel (the end of the build warning). None without the kernel.
    """
    key = (str(source), name, os.environ.get("IKFUSION_NO_COMPILE"))
    if key not in _FUNCTIONS:
        library = loaded_kernel(source, fallback)
        function = None if library is None else getattr(library, name)
        if function is not None:
            function.restype = ctypes.c_int64
            function.argtypes = [ctypes.c_void_p]
        _FUNCTIONS[key] = function
    return _FUNCTIONS[key]


def kernel_warnings() -> list[str]:
    """Why a kernel could not be built in this process (empty when all were, or not tried)."""
    return list(_WARNINGS)


class ArrayAddresses:
    """The addresses of the arrays a kernel reads, remembered by identity.

    Each array is held while remembered (its id cannot pass to another array); past
    ``limit`` arrays the memory is cleared. For arrays a caller passes again and again (a QP
    buffer's views, a task's weights): one dictionary lookup instead of ``ctypes.data``.
    """

    def __init__(self, limit: int = 64) -> None:
        self._known: dict[int, tuple[np.ndarray, int]] = {}
        self._limit = limit

    def of(self, a: np.ndarray, valid: Callable[[np.ndarray], bool], what: str) -> int:
        """The address of ``a``, checked by ``valid`` the first time (ValueError ``what``)."""
        known = self._known.get(id(a))
        if known is None:
            if not valid(a):
                raise ValueError(what)
            if len(self._known) > self._limit:
                self._known.clear()
            known = self._known[id(a)] = (a, int(a.ctypes.data))
        return known[1]
