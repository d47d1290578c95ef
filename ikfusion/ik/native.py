"""Native builds of CasADi functions: compiled once, cached on disk, checked before loading.

When a C compiler is on the machine, the solver's step functions (:mod:`.compiled`) are compiled
to a shared library cached under ``$IKFUSION_CACHE`` (default ``~/.cache/ikfusion``); CasADi's
virtual machine is the fallback (and the choice when ``IKFUSION_NO_COMPILE`` is set). The
library's name holds a hash of the generating source (:func:`generator_fingerprint`), the CasADi
version and the compiler's identity; its content hash is recorded beside it when it is built and
checked before every load (a mismatch is rebuilt, never loaded): :mod:`ikfusion.native.build`
does the build, the record and the check; this module says what to generate and how to load it.

:class:`.bound_function.BoundFunction` evaluates a function on preallocated NumPy buffers.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import tempfile
import weakref
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from .. import rotations as numpy_rotations
from .. import rotations_casadi
from ..native import build as native_build
from ..native.build import cache_dir as cache_dir  # re-exported (tree_solve, tests)
from ..native.build import compile_shared, compiler_identity
from ..native.build import find_compiler as find_compiler
from ..paths import module_source
from .bound_function import BoundFunction as BoundFunction  # re-exported (retarget uses them)
from .bound_function import column_major as column_major

#: What is used when the step functions cannot be compiled (the end of the warning).
FALLBACK = "CasADi's virtual machine is used instead, several times slower"

#: A library's file name (it holds the build key) -> that library opened by ctypes, once per
#: process (a kernel calls its functions through their own pointers)
_HANDLES: dict[str, ctypes.CDLL] = {}
#: Each function loaded from a library -> that library opened by ctypes
_LIBRARY_OF: weakref.WeakKeyDictionary[ca.Function, ctypes.CDLL] = weakref.WeakKeyDictionary()


def generator_fingerprint() -> str:
    """SHA-256 of the source that generates the step functions and builds them.

    That is :mod:`.compiled`, :mod:`.compiled_sensed`, :mod:`.compiled_points`,
    :mod:`.casadi_kinematics`, :mod:`.compiled_ranges`, :mod:`.compiled_joint_tasks` and
    :mod:`.compiled_blocks` (the expressions), this module and :mod:`ikfusion.native.build` (the
    build), the CasADi rotation twin and the NumPy module holding their shared epsilon policy.
    """
    from . import (  # imported late: no cycle
        casadi_kinematics,
        compiled,
        compiled_blocks,
        compiled_joint_tasks,
        compiled_points,
        compiled_ranges,
        compiled_sensed,
    )

    digest = hashlib.sha256()
    for module in (compiled.__name__, compiled_sensed.__name__, compiled_points.__name__,
                   casadi_kinematics.__name__, compiled_ranges.__name__,
                   compiled_joint_tasks.__name__, compiled_blocks.__name__, __name__,
                   native_build.__name__, rotations_casadi.__name__, numpy_rotations.__name__):
        digest.update(module_source(module).read_bytes())  # (a compiled module's, not its .so)
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


def _library(key: str, names: Sequence[str], functions: Sequence[ca.Function] = ()
             ) -> native_build.NativeLibrary[list[ca.Function]]:
    """The library of structure ``key`` holding ``names`` (built from ``functions``)."""
    def build(compiler: str, output: Path) -> None:
        with tempfile.TemporaryDirectory(dir=output.parent) as tmp:
            source = Path(tmp) / "ik_step.c"
            generator = ca.CodeGenerator(source.name, {"with_header": False})
            for function in functions:
                generator.add(function)
            generator.generate(f"{tmp}{os.sep}")
            compile_shared(compiler, source, output)

    return native_build.NativeLibrary(
        what="solver's step function", fallback=FALLBACK,
        path=lambda folder, compiler: library_path(folder, key, compiler), build=build,
        load=lambda copy: _load(copy, names))


def _load(copy: Path, names: Sequence[str]) -> list[ca.Function]:
    """The functions ``names`` of the verified private ``copy``, its ctypes handle recorded."""
    functions = [ca.external(name, str(copy)) for name in names]
    handle = _HANDLES.get(copy.name)
    if handle is None:
        handle = _HANDLES[copy.name] = ctypes.CDLL(str(copy))
    for function in functions:
        _LIBRARY_OF[function] = handle
    return functions


def compiled_library(function: ca.Function) -> ctypes.CDLL | None:
    """The verified library ``function`` was loaded from, opened by ctypes; None if none.

    Its symbols are CasADi's C interface: ``<name>(arg, res, iw, w, mem)`` and
    ``<name>_work(&sz_arg, &sz_res, &sz_iw, &sz_w)``, ``casadi_int`` as ``long long``.
    """
    return _LIBRARY_OF.get(function)


def cached_functions(key: str, names: Sequence[str]) -> list[ca.Function] | None:
    """The functions ``names`` of structure ``key`` when already built and verified, else None.

    Lets a caller skip building the CasADi graphs when their library is cached (building them
    takes longer than loading). None too without a C compiler or with ``IKFUSION_NO_COMPILE``.
    """
    return native_build.cached_library(_library(key, names))


def native_functions(functions: Sequence[ca.Function], key: str
                     ) -> tuple[list[ca.Function] | None, str | None]:
    """The functions compiled to one shared library, cached on disk and checked before loading.

    A library is loaded only when its content hash equals the one recorded when it was built
    (``<library>.sha256``); otherwise it is rebuilt. The first build says so on stderr (one
    line); a failed build says so too and is returned as a warning
    (:func:`ikfusion.native.build.native_library`).

    Args:
        functions: CasADi functions to compile together.
        key: Their structure key (:func:`structure_key`).

    Returns:
        ``(functions loaded from the library or None, warning or None)``: None without a C
        compiler or with ``IKFUSION_NO_COMPILE`` set (no warning), or when the build failed
        (with a warning naming why; CasADi's virtual machine is used then).
    """
    names = [f.name() for f in functions]
    return native_build.native_library(_library(key, names, functions))
