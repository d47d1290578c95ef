"""C functions of small kernels outside the solver, compiled once and cached like the solver's.

A kernel is a C file beside its module with functions ``int64_t f(const struct ... *)``: one
pointer to a struct of the arguments (one cheap ctypes call). It is built by the solver's
machinery (:func:`ikfusion.ik.native_kernel.loaded_kernel`: the machine's C compiler, the cache
folder, a content check); without a compiler, with ``IKFUSION_NO_COMPILE`` or when the build
fails (then with a warning), the caller's NumPy path runs instead.
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import Callable
from pathlib import Path

#: (C file, function, IKFUSION_NO_COMPILE) -> the function (None: without the kernel)
_FUNCTIONS: dict[tuple[str, str, str | None], Callable[..., int] | None] = {}


def c_function(source: Path, name: str, fallback: str) -> Callable[..., int] | None:
    """The function ``name`` of the C file ``source``, taking one pointer, returning int64.

    Looked up once per process and setting. ``fallback``: what is used without the kernel
    (the end of the build warning). None without the kernel.
    """
    key = (str(source), name, os.environ.get("IKFUSION_NO_COMPILE"))
    if key not in _FUNCTIONS:
        from .ik.native_kernel import loaded_kernel  # imported late: ik imports the model

        library = loaded_kernel(source, fallback)
        function = None if library is None else getattr(library, name)
        if function is not None:
            function.restype = ctypes.c_int64
            function.argtypes = [ctypes.c_void_p]
        _FUNCTIONS[key] = function
    return _FUNCTIONS[key]
