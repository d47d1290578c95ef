"""Delimited numbers read by a small C kernel (``number_parse.c``), the common case of tables.

NumPy's ``loadtxt`` converts each field through Python's string-to-double; the kernel reads
a whole block in one pass when every field is empty (NaN, as the Python path fills it) or
plain (``[+-]digits[.digits]``, its digits as one integer at most 2**53, at most 22 decimals):
an exact integer divided by an exact power of ten (one correctly rounded division, the
correctly rounded value: the same double as ``loadtxt``). Any other field (exponent, NaN,
padding, CR), a line with another field count or a blank line of a one-column table leaves
the block to the Python path (None), which then reads it or names the fault as before. Compiled once
with the machine's C compiler and cached (:func:`ikfusion.native.kernel.c_function`);
without it (no compiler, ``IKFUSION_NO_COMPILE``) ``loadtxt`` reads every block.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..native.kernel import c_function, kernel_source

#: What is used when the kernel cannot be compiled (the end of the build warning).
FALLBACK = "NumPy's loadtxt reads the IMU tables instead"

_P, _N = ctypes.c_void_p, ctypes.c_int64


class _ParseBlock(ctypes.Structure):
    """``struct parse_block`` of ``number_parse.c``."""

    _fields_ = [("text", _P), ("size", _N), ("delimiter", _N), ("lines", _N), ("width", _N),
                ("out", _P)]


def kernel_table(text: str, delimiter: str, width: int) -> np.ndarray | None:
    """(lines, width) floats of a block, NaN where a field is empty; None: the Python path.

    Args:
        text: The lines joined by newlines (no trailing newline), ASCII for the kernel.
        delimiter: One-character field delimiter.
        width: Fields per line.
    """
    if len(delimiter) != 1 or delimiter == "\n" or width < 1 or not text.isascii():
        return None
    function = c_function(kernel_source(__name__, "number_parse.c"), "parse_block", FALLBACK)
    if function is None:
        return None
    data = text.encode()
    lines = data.count(b"\n") + 1
    out = np.empty((lines, width))
    call = _ParseBlock(ctypes.cast(ctypes.c_char_p(data), ctypes.c_void_p).value, len(data),
                       ord(delimiter), lines, width, out.ctypes.data)
    return out if function(ctypes.byref(call)) == 0 else None
