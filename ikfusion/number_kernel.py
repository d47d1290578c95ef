"""The digits of :mod:`ikfusion.number_text`'s fast path written by a small C kernel.

NumPy writes the digits of a block of values in about thirty array passes and then drops the
NUL padding of its fixed-width slots; the C kernel (``number_text.c``) writes each value's
digits once, straight into the text. It receives the same rounded integers (``|v| * 10**d``,
exact below 2**52, checked by :mod:`ikfusion.number_text` to round as ``%`` does) and the
values' sign bits, and only splits integers into digits: the text is the NumPy path's, byte for
byte. The kernel is compiled once with the machine's C compiler and cached
(:func:`ikfusion.native.kernel.c_function`); without it (no compiler,
``IKFUSION_NO_COMPILE``) NumPy writes the digits.
"""

from __future__ import annotations

import ctypes

import numpy as np

from .native.kernel import c_function, kernel_source

#: What is used when the kernel cannot be compiled (the end of the build warning).
FALLBACK = "NumPy writes the numbers of the result files instead"
#: Most bytes of one field: a sign, 16 integer digits (below 2**52), a point, 9 decimals.
FIELD_BYTES = 28

_P, _N = ctypes.c_void_p, ctypes.c_int64


class _FixedRows(ctypes.Structure):
    """``struct fixed_rows`` of ``number_text.c``."""

    _fields_ = [("rows", _P), ("whole", _P), ("n", _N), ("k", _N), ("decimals", _N),
                ("literals", _P), ("bounds", _P), ("out", _P), ("field_decimals", _P)]


class Literals:
    """A row format's literal texts as the kernel reads them (built once per format)."""

    def __init__(self, encoded: list[bytes]) -> None:
        joined = b"".join(encoded)
        self.text = np.frombuffer(joined or b"\0", np.uint8)
        self.bounds = np.concatenate([[0], np.cumsum([len(e) for e in encoded])]).astype(np.int64)
        self.row_bytes = len(joined)
        self.out = np.empty(0, np.uint8)

    def room(self, size: int) -> np.ndarray:
        """A text buffer of at least ``size`` bytes, kept for the next block (reused)."""
        if len(self.out) < size:
            self.out = np.empty(size, np.uint8)
        return self.out


def kernel_text(literals: Literals, decimals: int, rows: np.ndarray, whole: np.ndarray,
                field_decimals: np.ndarray | None = None) -> bytes | None:
    """Rows whose every value takes the fast path, as text (bytes); None without the kernel.

    Args:
        literals: The row format's texts around its k fields.
        decimals: Digits after the point (0 to 9).
        rows: (n, k) values (their signs).
        whole: (n, k) ``|rows| * 10**decimals`` rounded, integers below 2**52 as floats.
        field_decimals: (k,) int64 digits after the point of each field instead (0 to 9).
    """
    function = c_function(kernel_source(__name__, "number_text.c"), "fixed_rows", FALLBACK)
    if function is None:
        return None
    n, k = rows.shape
    rows = np.ascontiguousarray(rows, dtype=float)
    whole = np.ascontiguousarray(whole, dtype=float)
    out = literals.room(n * (literals.row_bytes + k * FIELD_BYTES))
    call = _FixedRows(rows.ctypes.data, whole.ctypes.data, n, k, decimals,
                      literals.text.ctypes.data, literals.bounds.ctypes.data, out.ctypes.data,
                      None if field_decimals is None else field_decimals.ctypes.data)
    length = function(ctypes.byref(call))
    return out[:length].tobytes()
