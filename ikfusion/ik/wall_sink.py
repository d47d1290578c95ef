"""The soft wall's sink past the limits in one native call (``wall_sink.c``).

:meth:`.limits.soft_wall.SoftWall.update` asks every frame how far each anatomical angle would
sink past its limits and whether any reaches one (most frames none does). With NumPy that is
eight calls on arrays of a few dozen numbers; the kernel (compiled once like the step function,
:func:`ikfusion.native.kernel.loaded_kernel`) makes the same operations in the same order, so the
numbers are the same bit for bit. Without a C compiler (or with ``IKFUSION_NO_COMPILE``) the
caller keeps its NumPy path.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..native.kernel import kernel_source, loaded_kernel
from .kernel_arguments import WallArguments

#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "NumPy computes the soft wall's sink instead"


class WallSink:
    """The sink of the angles of one set of limits, frame after frame.

    The angles are copied into two buffers taken in turn (the last frame's, the one before), so
    the kernel's arguments are set up once per buffer.

    Args:
        library: The loaded kernel.
        limit: (2, joints, 3) the upper limits and the negated lower ones [rad].
    """

    def __init__(self, library: ctypes.CDLL, limit: np.ndarray) -> None:
        self._limit = np.ascontiguousarray(limit, dtype=float)
        count = self._limit[0].size
        self._angles = (np.zeros(count), np.zeros(count))
        #: The last sink (2, joints, 3) [rad] (overwritten by the next call).
        self.sunk = np.zeros(self._limit.shape)
        a, b = (int(x.ctypes.data) for x in self._angles)
        self._args = tuple(WallArguments(now, before, self._limit.ctypes.data,
                                         self.sunk.ctypes.data, 0.0, 0.0, count)
                           for now, before in ((a, b), (b, a)))
        self._at = tuple(ctypes.addressof(arg) for arg in self._args)
        self._turn = 0  # the buffer the next angles go to
        self._kernel = library.ik_wall_sink
        self._kernel.restype = ctypes.c_int
        self._kernel.argtypes = [ctypes.c_void_p]

    def first(self, angles: np.ndarray) -> None:
        """Keep ``angles`` (joints, 3) [rad] as the frame before the next :meth:`reaches`."""
        self._angles[1 - self._turn][:] = angles.reshape(-1)

    def reaches(self, angles: np.ndarray, grow: float, drift: float) -> bool:
        """Whether an angle of ``angles`` (joints, 3) [rad] sinks past a limit (:attr:`sunk`).

        ``grow``, ``drift``: the factors of :meth:`.limits.soft_wall.SoftWall.update`; the
        angles are kept as the frame before the next call.
        """
        turn = self._turn
        self._angles[turn][:] = angles.reshape(-1)
        args = self._args[turn]
        if args.grow != grow or args.drift != drift:
            args.grow, args.drift = grow, drift
        self._turn = 1 - turn
        return bool(self._kernel(self._at[turn]))


def wall_sink(limit: np.ndarray) -> WallSink | None:
    """The native sink of ``limit`` (:class:`WallSink`); None without the kernel."""
    library = loaded_kernel(kernel_source(__name__, "wall_sink.c"), FALLBACK)
    return None if library is None else WallSink(library, limit)
