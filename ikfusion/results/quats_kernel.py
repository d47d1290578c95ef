""":func:`ikfusion.rotations.matrix_to_quat_wxyz` of many matrices by a small C kernel.

NumPy's formulas (``_quat_wxyz_at_once``) in C (``segment_quats.c``), the same operations in
the same order: the same numbers, in one pass instead of some forty array operations. Compiled
once and cached (:func:`ikfusion.native.kernel.c_function`); without it (no compiler,
``IKFUSION_NO_COMPILE``) or for matrices holding NaN or infinities, NumPy converts.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..native.kernel import c_function, kernel_source

#: What is used when the kernel cannot be compiled (the end of the build warning).
FALLBACK = "NumPy converts the segment rotations of the result files instead"


class _Quats(ctypes.Structure):
    """``struct quats`` of ``segment_quats.c``."""

    _fields_ = [("R", ctypes.c_void_p), ("n", ctypes.c_int64), ("q", ctypes.c_void_p)]


def kernel_quats_wxyz(R: np.ndarray) -> np.ndarray | None:
    """Quaternions (w, x, y, z), ``w >= 0``, shape ``S + (4,)`` of ``R`` ``S + (3, 3)``, or None.

    None without the kernel or when ``R`` holds a non-finite value.
    """
    function = c_function(kernel_source(__name__, "segment_quats.c"), "matrix_quats", FALLBACK)
    if function is None or not np.isfinite(R).all():
        return None
    M = np.ascontiguousarray(R, dtype=float)
    q = np.empty(M.shape[:-2] + (4,))
    function(ctypes.byref(_Quats(M.ctypes.data, M.size // 9, q.ctypes.data)))
    return q
