""":func:`ikfusion.model.angle_continuity.continuous_series` by a small C kernel.

The NumPy path spends about thirty array passes per joint (a vectorised guess, then a check
against the frame-by-frame rule); the C kernel (``angle_continuity.c``) runs the rule itself,
frame by frame, with the same floating-point operations in the same order: the same numbers.
Compiled once and cached (:func:`ikfusion.native.kernel.c_function`); without it (no
compiler, ``IKFUSION_NO_COMPILE``) the NumPy path runs.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..native.kernel import c_function, kernel_source

#: What is used when the kernel cannot be compiled (the end of the build warning).
FALLBACK = "NumPy makes joint angle series continuous instead"


class _Series(ctypes.Structure):
    """``struct series`` of ``angle_continuity.c``."""

    _fields_ = [("angles", ctypes.c_void_p), ("frames", ctypes.c_int64),
                ("joints", ctypes.c_int64)]


def continuous_in_place(flat: np.ndarray) -> bool:
    """Make the series ``flat`` (N, J, 3) [rad] continuous in place; False without the kernel.

    Args:
        flat: C-contiguous float64 angles, frames first, each joint's triple in sequence order.
    """
    function = c_function(kernel_source(__name__, "angle_continuity.c"), "continuous_series",
                          FALLBACK)
    if function is None:
        return False
    if flat.dtype != np.float64 or not flat.flags.c_contiguous or flat.ndim != 3 \
            or flat.shape[2] != 3:
        raise ValueError("angles must be a C-contiguous float64 (N, J, 3) array")
    function(ctypes.byref(_Series(flat.ctypes.data, flat.shape[0], flat.shape[1])))
    return True
