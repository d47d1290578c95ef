"""Delimited numbers read by a small C kernel (``number_parse.c``), the common case of tables.

NumPy's ``loadtxt`` converts each field through Python's string-to-double; the kernel reads
the plain fields (``[+-]digits[.digits]``, its digits as one integer at most 2**53, at most
22 decimals) of a whole block
in one pass by an exact integer divided by an exact power of ten (one correctly rounded
division, the correctly rounded value: the same double as ``loadtxt``). Any other field
(exponent, NaN, padding), an empty kept field or a line with another field count leaves the
block to ``loadtxt`` (None), which then reads it or names the fault as before. Compiled once
with the machine's C compiler and cached (:func:`ikfusion.native.kernel.c_function`);
without it (no compiler, ``IKFUSION_NO_COMPILE``) ``loadtxt`` reads every block.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from ..native.kernel import c_function

#: What is used when the kernel cannot be compiled (the end of the build warning).
FALLBACK = "NumPy's loadtxt reads the IMU tables instead"

_P, _N = ctypes.c_void_p, ctypes.c_int64


class _ParseBlock(ctypes.Structure):
    """``struct parse_block`` of ``number_parse.c``."""

    _fields_ = [("text", _P), ("size", _N), ("delimiter", _N), ("lines", _N), ("width", _N),
                ("keep", _P), ("out", _P)]


def kernel_table(text: str, delimiter: str, keep: np.ndarray, lines: int) -> np.ndarray | None:
    """(lines, kept columns) floats of a block of ``lines`` lines, or None (``loadtxt`` then).

    Args:
        text: The lines joined by newlines (no trailing newline).
        delimiter: One-character field delimiter.
        keep: (width,) bool, the columns read (in order).
        lines: Lines of ``text``.
    """
    if len(delimiter) != 1 or not lines:
        return None
    function = c_function(Path(__file__).with_name("number_parse.c"), "parse_block", FALLBACK)
    if function is None:
        return None
    data = text.encode()
    if len(data) != len(text):  # a character beyond ASCII: loadtxt
        return None
    flags = np.ascontiguousarray(keep, dtype=np.uint8)
    kept = int(np.count_nonzero(flags))
    if not kept:  # no field to read (loadtxt would also drop blank lines)
        return None
    out = np.empty((lines, kept))
    call = _ParseBlock(ctypes.cast(ctypes.c_char_p(data), ctypes.c_void_p).value, len(data),
                       ord(delimiter), lines, len(flags), flags.ctypes.data, out.ctypes.data)
    return out if function(ctypes.byref(call)) == 0 else None
