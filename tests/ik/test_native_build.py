"""The native build's compiler options: a compiler without the inlining option still builds."""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

from ikfusion.native.build import INLINE_OWN_CALLS, compile_shared, find_compiler

SOURCE = """
double square(double x) { return x * x; }
double sum_of_squares(double x, double y) { return square(x) + square(y); }
"""


@pytest.fixture
def compiler() -> str:
    found = find_compiler()
    if found is None:
        pytest.skip("no C compiler on this machine")
    return found


def _built(compiler: str, folder: Path) -> ctypes.CDLL:
    source = folder / "k.c"
    source.write_text(SOURCE)
    library = folder / "k.so"
    compile_shared(compiler, source, library)
    function = ctypes.CDLL(str(library)).sum_of_squares
    function.restype, function.argtypes = ctypes.c_double, [ctypes.c_double, ctypes.c_double]
    return function


def test_a_library_is_built_with_its_own_calls_inlinable(compiler: str, tmp_path: Path) -> None:
    assert _built(compiler, tmp_path)(3.0, 4.0) == 25.0


def test_a_compiler_refusing_the_inlining_option_builds_without_it(compiler: str,
                                                                   tmp_path: Path) -> None:
    """A compiler that fails on the option (an old one) builds the library without it."""
    fussy = tmp_path / "fussy-cc"
    fussy.write_text(f"#!/bin/sh\nfor a in \"$@\"; do [ \"$a\" = {INLINE_OWN_CALLS} ] && "
                     f"{{ echo 'unknown option' >&2; exit 1; }}; done\nexec {compiler} \"$@\"\n")
    fussy.chmod(0o755)
    assert _built(str(fussy), tmp_path)(1.5, 2.0) == 6.25
