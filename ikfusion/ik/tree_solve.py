"""The closed-form step (:mod:`.equality_qp`) on the kinematic tree's sparsity, in native code.

A step's ``H`` couples a tangent column only with its ancestors and descendants in the
kinematic tree (every task's Jacobian row of a frame lies on that frame's ancestors; the
posture, chain and damping terms on a joint and its neighbours): factored leaves first,
``H = U D U^T`` with ``U``'s column ``k`` on ``k``'s ancestors only, nothing fills in, and the
factorisation costs a few thousand operations instead of a dense Cholesky's ``nv^3 / 6``. The
kernel (``tree_solve.c``, compiled once like the step function,
:func:`ikfusion.native.kernel.native_kernel`) reads the step's packed QP (:class:`.qp.QpBuffer`) in
place and returns the minimiser on the equality rows with whether it satisfies the inequality
rows: one call where the NumPy path makes a dozen. An ``H`` with a nonzero outside the tree's
pattern is refused (the caller falls back to LAPACK), so the answer never depends on the tasks
keeping to it.
"""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..native.kernel import ArrayAddresses, kernel_source, loaded_kernel
from .equality_qp import DEPENDENT_ROWS
from .kernel_arguments import ActiveRows, TreePlan

if TYPE_CHECKING:
    from .limits.joint_range import LinearisedRanges

#: The kernel's answers (see ``tree_solve.c``); :data:`GOES_ON`: :meth:`TreeClosedForm.step`'s
#: minimiser satisfies the QP's rows but crosses a range row left out of it or passes a bound.
SOLVED, CROSSES, FAILED, NOT_TREE, NOT_FINITE, GOES_ON = 0, 1, 2, 3, 4, 5


def column_parents(model: pin.Model) -> np.ndarray:
    """(nv,) the parent of each tangent column in the kinematic tree (-1 for the first).

    What Pinocchio's ``Data.parents_fromRow`` holds (the row structure its own sparse Cholesky
    of the joint-space inertia factors on), from the model's tree alone (building a ``Data``
    costs milliseconds): a joint's columns form a chain, its first column's parent is the last
    column of its parent joint (-1 under the universe).
    """
    parents = np.full(model.nv, -1, dtype=int)
    for joint in range(1, model.njoints):
        first, count = model.idx_vs[joint], model.nvs[joint]
        parent = model.parents[joint]
        if count:
            parents[first] = model.idx_vs[parent] + model.nvs[parent] - 1 if parent else -1
            parents[first + 1:first + count] = np.arange(first, first + count - 1)
    return parents


def ancestors(parents: np.ndarray) -> list[list[int]]:
    """Each column's ancestors, nearest first (decreasing: a parent precedes its children)."""
    chains: list[list[int]] = []
    for k, p in enumerate(parents):
        if p >= k:
            raise ValueError("a tangent column precedes its parent")
        chains.append([] if p < 0 else [int(p), *chains[p]])
    return chains


#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "LAPACK solves the closed-form steps instead"

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
        self._work_rows = -1  # the most equality rows the work array was sized for
        self._plan = TreePlan(self._ptr.ctypes.data, self._anc.ctypes.data, self._off.ctypes.data,
                              self.x.ctypes.data, None, DEPENDENT_ROWS, n, len(self._off))
        self._plan_at = ctypes.addressof(self._plan)
        self._kernel = library.ik_tree_closed_form
        self._kernel.restype = ctypes.c_int
        self._kernel.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_void_p]
        # id of a packed array -> (the array, kept alive so its id stays its own; its address)
        self._addresses = ArrayAddresses()
        self._last_packed: tuple[np.ndarray | None, int] = (None, 0)  # the last one and its address
        self._step = library.ik_active_step
        self._step.restype = ctypes.c_int
        self._step.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                               ctypes.c_void_p]
        self._check = library.ik_active_check
        self._check.restype = ctypes.c_int
        self._check.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        # the rows left out (copied in by step): rooms (2, angles), up and down, lb then ub
        self._rooms = np.zeros((2, 0))
        self._in_qp = np.zeros((2, 0), dtype=bool)
        self._bounds = np.zeros((2, n))
        self._active = ActiveRows(None, None, self._bounds.ctypes.data, None, None, 0.0, 0, 0)
        self._active_at = ctypes.addressof(self._active)
        self._G: np.ndarray | None = None  # the range rows' G the kernel reads (kept alive)
        # the caller's rooms and masks, and bounds, the kernel reads in place (kept alive, so
        # the same objects again are the same memory); None: copied at the next call
        self._rows_read: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._bounds_read: tuple[np.ndarray, np.ndarray] | None = None
        self._distance = library.ik_least_distance
        self._distance.restype = ctypes.c_int
        self._distance.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_void_p,
                                   ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        self._distance_step = library.ik_least_distance_step
        self._distance_step.restype = ctypes.c_int
        self._distance_step.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        self._u = np.zeros(n)  # DAQP's u, copied in for least_distance_step
        self._u_at = self._u.ctypes.data
        # (m_in, m_eq) -> (M, upper, lower) for least_distance_rows and their addresses
        self._distance_rows: dict[tuple[int, int], tuple[tuple[np.ndarray, ...],
                                                         tuple[int, ...]]] = {}

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
        return int(self._kernel(self._plan_at, m_in, m_eq, self._packed_at(packed, m_in, m_eq)))

    def step(self, packed: np.ndarray, m_in: int, m_eq: int, ranges: LinearisedRanges,
             up: np.ndarray, down: np.ndarray, bounds: tuple[np.ndarray, np.ndarray] | None,
             tolerance: float) -> int:
        """:meth:`solve`, then the rows left out of the QP and the bounds tested on :attr:`x`.

        The common step of :func:`.active_set.solve_with_active_set` (its QP without bounds) in
        one call: the minimiser is the step when it satisfies the QP's rows, crosses none of the
        range rows left out (an upper limit not in ``up`` is crossed when its rate passes
        ``room_up + tolerance``, a lower one likewise) and keeps within ``bounds`` widened by
        ``tolerance`` [rad or m].

        Args:
            packed: As :meth:`solve`.
            m_in: Its inequality rows.
            m_eq: Its equality rows.
            ranges: The step's linearised ranges (``G`` (angles, nv) C-contiguous).
            up: (angles,) the upper limits in the QP.
            down: (angles,) the lower limits in the QP.
            bounds: The velocity bounds ``(lb, ub)`` (nv,), or None.
            tolerance: How far a left-out row or a bound may be passed [rad or m].

        Returns:
            0 (:data:`SOLVED`): :attr:`x` is the step; :data:`GOES_ON`: :attr:`x` solves the
            QP but crosses a left-out row or passes a bound, or a rate lies so close to its
            limit that BLAS's summation of it (the Python loop's) could say so: the caller's
            loop decides from :attr:`x`; else :meth:`solve`'s answer (1 to 4).
        """
        if not self._read_limits(ranges, up, down, bounds, tolerance):
            raise ValueError("the ranges' G is not (angles, nv) C-contiguous")
        return int(self._step(self._plan_at, self._active_at, m_in, m_eq,
                              self._packed_at(packed, m_in, m_eq)))

    def passes_none(self, x: np.ndarray, ranges: LinearisedRanges, up: np.ndarray,
                    down: np.ndarray, bounds: tuple[np.ndarray, np.ndarray] | None,
                    tolerance: float) -> bool:
        """Whether the step ``x`` (n,) surely crosses no range row left out and passes no bound.

        :meth:`step`'s test of its minimiser (arguments as there) on another QP solution
        (DAQP's), copied into :attr:`x`: True when no rate passes its room and no entry its
        bound by more than ``tolerance``, whatever the summation order of the rates; False
        when one does or might (or ``ranges`` is not for the kernel): the caller's loop
        decides then.
        """
        if not self._read_limits(ranges, up, down, bounds, tolerance):
            return False
        self.x[:] = x
        return self._check(self._plan_at, self._active_at) == SOLVED

    def _read_limits(self, ranges: LinearisedRanges, up: np.ndarray, down: np.ndarray,
                     bounds: tuple[np.ndarray, np.ndarray] | None, tolerance: float) -> bool:
        """The kernel pointed at the limit rows and bounds (:meth:`step`); False: G unfit."""
        active, G = self._active, ranges.G
        if G is not self._G:  # the step function's output: the same array step after step
            if G.dtype != np.float64 or not G.flags.c_contiguous or G.shape[1] != self.n:
                return False
            angles = len(G)
            if self._rooms.shape[1] != angles:
                self._rooms = np.zeros((2, angles))
                self._in_qp = np.zeros((2, angles), dtype=bool)
                active.angles, self._rows_read = angles, None
            self._G, active.G = G, G.ctypes.data
        rows = self._rows_read
        if rows is None or ranges.rooms is not rows[0] or up is not rows[1] or \
                down is not rows[2]:
            self._read_rows(ranges.rooms, up, down)
        if bounds is None:
            active.has_bounds = 0
        else:
            active.has_bounds = 1
            kept = self._bounds_read
            if kept is None or bounds[0] is not kept[0] or bounds[1] is not kept[1]:
                self._read_bounds(bounds[0], bounds[1])
        active.tolerance = tolerance
        return True

    def _read_rows(self, rooms: np.ndarray, up: np.ndarray, down: np.ndarray) -> None:
        """The kernel pointed at ``rooms`` (2, angles), ``up`` and ``down`` (angles,) in place.

        Kept while they are the same arrays (a step writer's, written in place step after
        step); arrays of another layout are copied into the kernel's own, at every call.
        """
        active, angles = self._active, self._active.angles
        if _fits(rooms, np.float64, (2, angles)) and _fits(up, np.bool_, (angles,)) and \
                _fits(down, np.bool_, (angles,)):
            self._rows_read = (rooms, up, down)
            active.rooms, active.up, active.down = (
                rooms.ctypes.data, up.ctypes.data, down.ctypes.data)
            return
        np.copyto(self._rooms, rooms)
        np.copyto(self._in_qp[0], up)
        np.copyto(self._in_qp[1], down)
        self._rows_read = None
        active.rooms, active.up = self._rooms.ctypes.data, self._in_qp.ctypes.data
        active.down = active.up + angles

    def _read_bounds(self, lb: np.ndarray, ub: np.ndarray) -> None:
        """The kernel pointed at the bounds ``lb``, ``ub`` (n,) in place, else copied.

        In place when ``ub`` follows ``lb`` in memory (the kernel's layout: the rows of one
        (2, n) array, :meth:`.limits.velocity.VelocityLimit.bounds`'s), kept while the same
        arrays; else copied at every call.
        """
        n, active = self.n, self._active
        if _fits(lb, np.float64, (n,)) and _fits(ub, np.float64, (n,)) and \
                ub.ctypes.data == lb.ctypes.data + 8 * n:
            self._bounds_read, active.bounds = (lb, ub), lb.ctypes.data
            return
        np.copyto(self._bounds[0], lb)
        np.copyto(self._bounds[1], ub)
        self._bounds_read, active.bounds = None, self._bounds.ctypes.data

    def least_distance_rows(self, packed: np.ndarray, m_in: int, m_eq: int
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The packed QP's rows in the least-distance form on the tree factor, or None.

        :mod:`.least_distance`'s transform with ``L = U D^1/2`` (``H = L L^T``) instead of
        LAPACK's Cholesky factor: ``M = [G; A] L^-T`` and its bounds ``upper = [h; b] + M v``,
        ``lower = [-1e30; b] + M v`` with ``v = L^-1 c``, in buffers kept for this size
        (overwritten by the next call; DAQP may scale ``M``'s rows). The two factors differ by
        an orthogonal matrix, which leaves the rows' lengths and angles, so DAQP's iterations
        and step, as they are, to rounding. None when ``H`` is off the tree's pattern or not
        positive definite. :meth:`least_distance_step` turns DAQP's ``u`` into the step.
        """
        buffers = self._distance_rows.get((m_in, m_eq))
        if buffers is None:
            m = m_in + m_eq
            arrays = (np.zeros((m, self.n)), np.zeros(m), np.zeros(m))
            buffers = self._distance_rows[m_in, m_eq] = (
                arrays, tuple(a.ctypes.data for a in arrays))
        (M, upper, lower), (M_at, upper_at, lower_at) = buffers
        answer = self._distance(self._plan_at, m_in, m_eq, self._packed_at(packed, m_in, m_eq),
                                M_at, upper_at, lower_at)
        return (M, upper, lower) if answer == 0 else None

    def least_distance_step(self, u: np.ndarray) -> np.ndarray | None:
        """The step ``x = L^-T (u - v)`` (into :attr:`x`) from DAQP's ``u`` (n,).

        After :meth:`least_distance_rows`; None when the step is not finite.
        """
        self._u[:] = u  # (copied in: reading a fresh array's address costs 2 us)
        return self.x if self._distance_step(self._plan_at, self._u_at) == 0 else None

    def _packed_at(self, packed: np.ndarray, m_in: int, m_eq: int) -> int:
        """The address of the packed QP ``packed`` (checked and kept on first sight).

        The kernel's work array is grown for it first when it is too small.
        """
        n = self.n
        if m_eq > self._work_rows:  # (its size grows with the equality rows only)
            size = self._tree_entries + 2 * n + m_eq * (2 * n + m_eq + 2)
            if len(self._work) < size:
                self._work = np.zeros(2 * size)
                self._plan.work = self._work.ctypes.data
            self._work_rows = m_eq
        last, at = self._last_packed
        if packed is not last:  # a buffer's views are made once per size: their addresses too
            at = self._addresses.of(packed, lambda a: a.flags.c_contiguous and len(a) >= n * n
                                    + n + (m_in + m_eq) * (n + 1), "not a packed QP of this size")
            self._last_packed = (packed, at)  # (held here: the same object is the same memory)
        return at


def _fits(a: np.ndarray, dtype: type, shape: tuple[int, ...]) -> bool:
    """Whether ``a`` is C-contiguous of ``dtype`` and ``shape`` (a kernel reads it in place)."""
    return a.dtype == dtype and a.shape == shape and a.flags.c_contiguous


def tree_closed_form(model: pin.Model) -> TreeClosedForm | None:
    """The native closed-form step of ``model``, or None without the kernel.

    None without a C compiler, with ``IKFUSION_NO_COMPILE``, or after a failed build
    (:func:`ikfusion.native.kernel.kernel_warnings` says why): LAPACK solves the closed form then.
    """
    library = loaded_kernel(kernel_source(__name__, "tree_solve.c"), FALLBACK)
    return None if library is None else TreeClosedForm(library, column_parents(model))
