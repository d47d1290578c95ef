"""The closed-form step (:mod:`.equality_qp`) on the kinematic tree's sparsity, in native code.

A step's ``H`` couples a tangent column only with its ancestors and descendants in the
kinematic tree (every task's Jacobian row of a frame lies on that frame's ancestors; the
posture, chain and damping terms on a joint and its neighbours): factored leaves first,
``H = U D U^T`` with ``U``'s column ``k`` on ``k``'s ancestors only, nothing fills in, and the
factorisation costs a few thousand operations instead of a dense Cholesky's ``nv^3 / 6``. The
kernel (``tree_solve.c``, compiled once like the step function,
:func:`.native_kernel.native_kernel`) reads the step's packed QP (:class:`.qp.QpBuffer`) in
place and returns the minimiser on the equality rows with whether it satisfies the inequality
rows: one call where the NumPy path makes a dozen. An ``H`` with a nonzero outside the tree's
pattern is refused (the caller falls back to LAPACK), so the answer never depends on the tasks
keeping to it.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import numpy as np
import pinocchio as pin

from .equality_qp import DEPENDENT_ROWS
from .native_build import cache_dir, find_compiler
from .native_kernel import native_kernel

#: The kernel's answers (see ``tree_solve.c``).
SOLVED, CROSSES, FAILED, NOT_TREE, NOT_FINITE = 0, 1, 2, 3, 4

#: (cache folder, compiler, IKFUSION_NO_COMPILE) -> the kernel loaded (None: not built)
_LIBRARIES: dict[tuple[str, str | None, str | None], ctypes.CDLL | None] = {}
_WARNINGS: list[str] = []


def column_parents(model: pin.Model) -> np.ndarray:
    """(nv,) the parent of each tangent column in the kinematic tree (-1 for the first).

    Pinocchio's ``Data.parents_fromRow`` (the row structure its own sparse Cholesky of the
    joint-space inertia factors on): a joint's columns form a chain, its first column's parent
    is the last column of its parent joint.
    """
    return np.array(pin.Data(model).parents_fromRow, dtype=int)


def ancestors(parents: np.ndarray) -> list[list[int]]:
    """Each column's ancestors, nearest first (decreasing: a parent precedes its children)."""
    chains: list[list[int]] = []
    for k, p in enumerate(parents):
        if p >= k:
            raise ValueError("a tangent column precedes its parent")
        chains.append([] if p < 0 else [int(p), *chains[p]])
    return chains


class _Plan(ctypes.Structure):
    """What the kernel keeps from call to call (``struct plan`` of ``tree_solve.c``)."""

    _fields_ = [("ptr", ctypes.c_void_p), ("anc", ctypes.c_void_p), ("off", ctypes.c_void_p),
                ("x", ctypes.c_void_p), ("work", ctypes.c_void_p),
                ("dependent_rows", ctypes.c_double), ("n", ctypes.c_int),
                ("n_off", ctypes.c_int)]


class TreeClosedForm:
    """The native closed-form step of one model (:func:`tree_closed_form`).

    Args:
        library: The loaded kernel.
        parents: (nv,) :func:`column_parents`.
    """

    def __init__(self, library: ctypes.CDLL, parents: np.ndarray) -> None:
        n = len(parents)
        chains = ancestors(parents)
        self._ptr = np.cumsum([0] + [len(a) for a in chains]).astype(np.intc)
        self._tree_entries = int(self._ptr[-1])  # U's entries (its work array's first part)
        self._anc = np.array([a for chain in chains for a in chain], dtype=np.intc)
        inside = np.eye(n, dtype=bool)
        for k, chain in enumerate(chains):
            inside[k, chain] = True
        rows, cols = np.nonzero(~inside & np.tri(n, dtype=bool))
        self._off = (rows * n + cols).astype(np.int_)
        self.n = n
        #: The last minimiser (overwritten by the next call).
        self.x = np.zeros(n)
        self._work = np.zeros(0)
        self._plan = _Plan(self._ptr.ctypes.data, self._anc.ctypes.data, self._off.ctypes.data,
                           self.x.ctypes.data, None, DEPENDENT_ROWS, n, len(self._off))
        self._plan_at = ctypes.addressof(self._plan)
        self._kernel = library.ik_tree_closed_form
        self._kernel.restype = ctypes.c_int
        self._kernel.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_void_p]
        # id of a packed array -> (the array, kept alive so its id stays its own; its address)
        self._addresses: dict[int, tuple[np.ndarray, int]] = {}

    def solve(self, packed: np.ndarray, m_in: int, m_eq: int) -> int:
        """The closed-form step of the packed QP ``packed`` into :attr:`x`; the kernel's answer.

        Args:
            packed: A :class:`.qp.QpBuffer`'s packed ``H, c, G, h, A, b`` (C-contiguous).
            m_in: Its inequality rows.
            m_eq: Its equality rows.

        Returns:
            :data:`SOLVED` (:attr:`x` is the minimiser on the equality rows and satisfies the
            inequality rows), :data:`CROSSES` (it does not), :data:`FAILED` (``H`` or the
            equality rows' Gram matrix not numerically positive definite, or not finite),
            :data:`NOT_TREE` (``H`` off the tree's pattern: nothing solved) or
            :data:`NOT_FINITE` (the sum of the packed numbers is not finite, as
            :func:`.qp._check_finite` tests it: nothing solved).
        """
        n = self.n
        size = self._tree_entries + 2 * n + m_eq * (2 * n + m_eq + 2)
        if len(self._work) < size:
            self._work = np.zeros(2 * size)
            self._plan.work = self._work.ctypes.data
        known = self._addresses.get(id(packed))
        if known is None:  # a buffer's views are made once per size: their addresses too
            if not packed.flags.c_contiguous or len(packed) < n * n + n + (m_in + m_eq) * (n + 1):
                raise ValueError("not a packed QP of this size")
            if len(self._addresses) > 64:
                self._addresses.clear()
            known = self._addresses[id(packed)] = (packed, packed.ctypes.data)
        return int(self._kernel(self._plan_at, m_in, m_eq, known[1]))


def tree_closed_form(model: pin.Model) -> TreeClosedForm | None:
    """The native closed-form step of ``model``, or None without the kernel.

    None without a C compiler, with ``IKFUSION_NO_COMPILE``, or after a failed build
    (:func:`kernel_warnings` says why): LAPACK solves the closed form then.
    """
    key = (str(cache_dir()), find_compiler(), os.environ.get("IKFUSION_NO_COMPILE"))
    if key not in _LIBRARIES:  # once per process and setting (a failed build is not retried)
        library, warning = native_kernel(Path(__file__).with_name("tree_solve.c"))
        _LIBRARIES[key] = library
        if warning is not None:
            _WARNINGS.append(warning)
    library = _LIBRARIES[key]
    return None if library is None else TreeClosedForm(library, column_parents(model))


def kernel_warnings() -> list[str]:
    """Why the kernel could not be built in this process (empty when it was, or not tried)."""
    return list(_WARNINGS)
