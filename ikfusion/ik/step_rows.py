"""A step's QP written from the evaluated step function in native code (``step_rows.c``).

:func:`.frame_problem.build_frame_problem` turns the compiled step function's outputs into the
packed QP (:class:`.qp.QpBuffer`) with a few dozen NumPy calls: the ranges' rooms softened and
the rows near a limit, ``H`` and ``c``, the site targets', the root's and the swing feet's
position rows, the damping term, the Levenberg-Marquardt diagonal, the floor and the contact rows
(and the velocity bounds, :meth:`.VelocityLimit.bounds`). :class:`StepRows` does the same in
one call of a small C kernel (compiled once and cached like :mod:`.tree_solve`,
:func:`ikfusion.native.kernel.native_kernel`) for the common steps: contact rows
along the world axes, position targets of scalar weights without a reach, no column-shape target
and no persistence on the root's columns. The same numbers but for the summation order of the
position rows' ``J^T W J`` (round-off); every other step, and every step without a C compiler
(or with ``IKFUSION_NO_COMPILE``), takes the NumPy path.
"""

from __future__ import annotations

import ctypes
from operator import is_
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from ..native.kernel import ArrayAddresses, kernel_source, loaded_kernel
from .bound_function import BoundFunction
from .compiled import MIRRORED, CompiledKinematics
from .kernel_arguments import StepPlan, StepPoints
from .limits.base import Inequality
from .limits.joint_range import LinearisedRanges
from .qp import QpBuffer, QpProblem
from .tasks.base import Task
from .tasks.position import PositionTask

if TYPE_CHECKING:
    from .frame_problem import FrameTasks
    from .limits.velocity import VelocityLimit

#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "NumPy writes the steps' QPs instead"
#: The most swing points the kernel takes (its stack arrays); more: the NumPy path.
MAX_SWING = 64


def _address(a: np.ndarray) -> int:
    return int(a.ctypes.data)


def _c_float64(a: np.ndarray) -> bool:
    """Whether the kernel can read ``a`` as it stands (C-contiguous float64)."""
    return bool(a.flags.c_contiguous and a.dtype == np.float64)


def _flat(sparsity: ca.Sparsity, mirrored: bool = False) -> np.ndarray:
    """The flat positions (row * columns + column) of a sparsity's nonzeros, in their order.

    ``mirrored`` (a lower triangle): then those of the transposed entries (column * rows +
    row) after them.
    """
    rows, cols = (np.array(v, dtype=int) for v in sparsity.get_triplet())
    flat = rows * sparsity.size2() + cols
    if mirrored:
        flat = np.concatenate([flat, cols * sparsity.size1() + rows])
    return flat.astype(np.intc)


class StepFunctionRows:
    """The kernel's plan for one evaluated step function (its outputs' addresses).

    Args:
        library: The loaded kernel.
        step: The step function's buffers (:class:`.bound_function.BoundFunction`).
        function: Its CasADi function (the outputs' sparsity).
        contact_site: (contacts,) each contact point's row among the function's sites.
        rate_rows: (angles, 3) :func:`.frame_problem.rate_rows`.
        buffer: The QP buffer, already at its largest size (its array never moves).
        packed: That buffer's array.
    """

    def __init__(self, library: ctypes.CDLL, step: BoundFunction, function: ca.Function,
                 contact_site: np.ndarray, rate_rows: np.ndarray, packed: np.ndarray,
                 margin: float) -> None:
        nv = function.size1_out(0)
        angles = len(rate_rows)
        for i in (8, 9):
            if not function.sparsity_out(i).is_dense():
                raise NotImplementedError("a vector output is sparse")
        # the sites' positions: none without sites (then no row reads them)
        P = step.nonzeros(5) if function.sparsity_out(5).is_dense() else \
            np.zeros(function.size1_out(5))
        self.step = step
        self.G = step.output(7)
        # the arrays the kernel reads or writes, kept alive with it
        J = function.sparsity_out(6)
        rows, cols = (np.array(v, dtype=int) for v in J.get_triplet())
        order = np.argsort(rows, kind="stable")
        self._keep = [
            _flat(function.sparsity_out(0), 0 in MIRRORED), _flat(function.sparsity_out(1)),
            _flat(function.sparsity_out(7)),
            np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=J.size1()))]).astype(
                np.intc), cols[order].astype(np.intc), order.astype(np.intc),
            np.ascontiguousarray(rate_rows, dtype=np.intc),
            np.ascontiguousarray(contact_site, dtype=np.intc), P]
        H_flat, c_flat, G_flat, J_ptr, J_col, J_at, rates, sites, _ = self._keep
        self.rooms = np.zeros((2, angles))
        self.close = np.zeros((2, angles), dtype=bool)
        # its rows (upper, lower) as the same views step after step (a native reader of them
        # keeps their addresses while they are the same arrays, :meth:`.TreeClosedForm.step`)
        self.up_down = (self.close[0], self.close[1])
        self.work = np.zeros(2 * 3 * max(MAX_SWING, 1) * nv)
        self.moved = np.zeros(nv)
        self.root_target = np.zeros(3)
        self.wall_room = np.zeros(2 * angles)
        self.wall_room_at = _address(self.wall_room)
        n_sites = function.size1_out(5) // 3 - 1  # (and the root)
        # each position task's weights and targets copied here: (weights, targets, struct)
        self.site_task = (np.zeros(n_sites), np.zeros((n_sites, 3)), StepPoints(0, n_sites))
        self.swing = (np.zeros(len(contact_site)), np.zeros((len(contact_site), 3)),
                      StepPoints(0, len(contact_site)))
        self.rooms_raw = step.vectors(8, 2)
        self.room_up_raw = self.rooms_raw[0]
        self.plan = StepPlan(
            _address(step.nonzeros(0)), _address(H_flat), function.nnz_out(0),
            _address(step.nonzeros(1)), _address(c_flat), len(c_flat), _address(P),
            _address(step.nonzeros(6)), _address(J_ptr), _address(J_col), _address(J_at),
            _address(step.nonzeros(7)), _address(G_flat), len(G_flat), _address(self.G),
            _address(rates), _address(self.rooms_raw), _address(sites), nv, angles,
            function.size1_out(5) // 3 - 1, _address(self.rooms), _address(self.close),
            _address(packed), _address(self.work), 0, None, margin)
        self.plan.moved = _address(self.moved)
        self.plan.root_target = _address(self.root_target)
        for weights, targets, points in (self.site_task, self.swing):
            points.weight, points.targets = _address(weights), _address(targets)
        self.plan.site_task, self.plan.swing = self.site_task[2], self.swing[2]
        self.site_task = (*self.site_task[:2], self.plan.site_task)  # (the plan's own copy)
        self.swing = (*self.swing[:2], self.plan.swing)
        self.at = ctypes.addressof(self.plan)
        # the damping weights, velocity span and bounds arrays whose addresses the plan holds
        self.read_arrays: tuple[np.ndarray | None, ...] = (None, None, None)
        # the ranges every step returns: its rows and rooms, written in place by each step
        self.ranges = LinearisedRanges(self.G, self.rooms)
        self.kernel = library.ik_step_rows
        self.kernel.restype = ctypes.c_int
        self.kernel.argtypes = [ctypes.c_void_p]


    def set_points(self, points: tuple[np.ndarray, np.ndarray, StepPoints],
                   task: PositionTask | None, weights: np.ndarray | None) -> None:
        """A position task's rows on (its weight, the weights and targets copied) or off."""
        points[2].on = task is not None
        if task is not None:
            points[2].scale = task.weight
            points[0][:] = weights
            points[1][:] = task.targets


class StepRows:
    """The native writer of one model's step QPs (:func:`step_rows`).

    Args:
        library: The loaded kernel.
        buffer: The QP buffer the steps are built in.
        rate_rows: (angles, 3) :func:`.frame_problem.rate_rows`.
        contact_rows: (contacts,) the contact points' rows among the sites.
        margin: Range rows within this of a limit [rad].
    """

    def __init__(self, library: ctypes.CDLL, buffer: QpBuffer, rate_rows: np.ndarray,
                 contact_rows: np.ndarray, margin: float) -> None:
        self.library = library
        contacts, angles = len(contact_rows), len(rate_rows)
        # the buffer at its largest (every range row, a floor row per point, 3 contact rows):
        # its array does not move afterwards
        packed = buffer.views(2 * angles + contacts, 3 * contacts).packed
        if packed is None:
            raise ValueError("not a packed buffer")
        self.packed = packed
        self.buffer = buffer
        self.contact_rows = contact_rows
        self.margin = margin
        self._rate_rows = rate_rows
        self._plans: dict[int, StepFunctionRows] = {}
        # the floor's z rows, the contacts' held rows and their anchors copied here each step
        # (a copy is cheaper than the address of a new array)
        self._floor_rows = np.zeros(contacts, dtype=np.int64)
        self._held_rows = np.zeros(3 * contacts, dtype=np.int64)
        self._anchors = np.zeros((contacts, 3))
        # the arrays last copied there (held, so their ids stay theirs): the contact limit and
        # the floor replace these arrays, never write them in place, so the same array again
        # holds the same numbers and is not copied again
        self._copied: tuple[np.ndarray | None, ...] = (None, None, None)
        # (floor rows' first row, QP inequality rows) -> the floor rows' views of the buffer
        self._floors: dict[tuple[int, int], Inequality] = {}
        # the damping weights' address (the same array frame after frame)
        self._addresses = ArrayAddresses()

    def plan(self, step: BoundFunction, kinematics: CompiledKinematics,
             sites: bool | None) -> StepFunctionRows:
        """The plan of ``step``, evaluated with ``sites`` (made once per step function)."""
        made = self._plans.get(id(step))
        if made is None:  # the function :meth:`.CompiledKinematics.evaluate` chose
            points_function = kinematics.function_points
            few = sites is None and points_function is not None
            function = kinematics.function_no_sites if sites is False else \
                points_function if few and points_function is not None else kinematics.function
            points = np.arange(len(self.contact_rows)) if few else self.contact_rows
            made = self._plans[id(step)] = StepFunctionRows(
                self.library, step, function, points, self._rate_rows, self.packed,
                self.margin)
            plan = made.plan
            plan.floor_rows, plan.held_rows, plan.anchors = (
                _address(self._floor_rows), _address(self._held_rows), _address(self._anchors))
        return made

    def write(self, step: BoundFunction, kinematics: CompiledKinematics, sites: bool | None,
              tasks: FrameTasks, active: list[Task], error: np.ndarray | None,
              levenberg_marquardt: float, velocity: VelocityLimit | None = None
              ) -> tuple[QpProblem, LinearisedRanges, tuple[np.ndarray, np.ndarray],
                         Inequality | None, tuple[np.ndarray, np.ndarray] | None] | None:
        """The step's QP from the evaluated ``step``; None: a step for the NumPy path.

        Args:
            step: The step function evaluated at the configuration (``sites`` as passed).
            kinematics: The compiled step function.
            sites: What it was evaluated with.
            tasks: The solver's tasks and limits (no column-shape target this frame).
            active: The tasks of this frame.
            error: The damping task's error ``q ⊖ q_reference`` (nv,), or None without one.
            levenberg_marquardt: Damping of the step [1/rad^2].
            velocity: The velocity limit whose bounds the kernel writes too (``error`` is then
                the move since its previous frame, ``q ⊖ q_previous``); None: not here.

        Returns:
            The QP (views of the buffer), the ranges (``G`` and the rooms in place, valid until
            the next step), the masks (angles,) of the range rows in the QP (upper, lower; the
            same arrays step after step, written in place), the floor rows (None without
            contact points) and ``velocity``'s bounds (:meth:`.VelocityLimit.bounds`; None
            without a bound or without ``velocity``).
        """
        root, swing, contact, position = tasks.root, tasks.swing, tasks.contact, tasks.position
        held = contact.world_rows()
        root_on, swing_on = root in active, swing in active
        site_on = sites is True and position.has_targets()  # (in ``active``: every step)
        root_w = root.scalar_weights() if root_on else None
        swing_w = swing.scalar_weights() if swing_on else None
        site_w = position.scalar_weights() if site_on else None
        if held is None or (root_on and (root_w is None or root.reach is not None)) or \
                (swing_on and (swing_w is None or swing.reach is not None)) or \
                (site_on and (site_w is None or position.reach is not None
                              or len(site_w) > MAX_SWING)):
            return None
        made = self._plans.get(id(step)) or self.plan(step, kinematics, sites)
        plan = made.plan
        room = tasks.joint_range.wall_room(made.G, made.room_up_raw)
        if room is None:
            plan.wall_room = None
        else:
            made.wall_room[:] = room.reshape(-1)
            plan.wall_room = made.wall_room_at
        contacts = len(self.contact_rows)
        n_floor = n_held = 0
        if contacts:
            floor_rows, anchors = tasks.floor.z_rows(), contact.anchors
            n_floor, n_held = len(floor_rows), len(held)
            last_floor, last_held, last_anchors = self._copied
            if floor_rows is not last_floor:
                self._floor_rows[:n_floor] = floor_rows
            if held is not last_held:
                self._held_rows[:n_held] = held
            if anchors is not last_anchors:
                np.copyto(self._anchors, anchors)
            self._copied = (floor_rows, held, anchors)
            plan.floor_z = tasks.floor.floor_z
        plan.n_floor, plan.n_held = n_floor, n_held
        plan.root_on = root_on
        if root_w is not None:
            plan.root_weight = root.weight * root_w[0]
            made.root_target[:] = root.targets[0]
        made.set_points(made.site_task, position if site_on else None, site_w)
        made.set_points(made.swing, swing if swing_on else None, swing_w)
        if error is not None:
            made.moved[:] = error
        bounds = self._read_arrays(made, None if error is None else tasks.damping.weights,
                                   None if error is None else velocity)
        plan.levenberg_marquardt = levenberg_marquardt
        below = made.kernel(made.at)
        qp = self.buffer.views(below + n_floor, n_held)
        if qp.packed is None or qp.packed.base is not self.packed.base:
            raise RuntimeError("the QP buffer moved: the kernel wrote its old array")
        floor = self._floors.get((below, n_floor)) if contacts else None
        if contacts and floor is None:  # (views of the buffer, whose array never moves)
            floor = self._floors[below, n_floor] = Inequality(qp.G[below:], qp.h[below:])
        return qp, made.ranges, made.up_down, floor, bounds

    def _read_arrays(self, made: StepFunctionRows, damping: np.ndarray | None,
                     velocity: VelocityLimit | None) -> tuple[np.ndarray, np.ndarray] | None:
        """The damping weights (nv,) and ``velocity``'s bounds given to ``made``'s kernel.

        None: no damping term, no bounds written. Their addresses are set only when the arrays
        are not those of the last step (held there: their ids stay theirs). Returns the
        bounds the kernel writes (:meth:`.VelocityLimit.bounds`), or None.
        """
        span = None if velocity is None else velocity.span()
        rows, bounds = (None, None) if velocity is None or span is None else \
            velocity.bound_rows
        arrays = (damping, span, rows)
        if not all(map(is_, arrays, made.read_arrays)):
            plan, addresses = made.plan, self._addresses
            plan.damping, plan.span, plan.bounds = (
                None if a is None else addresses.of(a, _c_float64, "not a C-contiguous "
                                                    "float64 array") for a in arrays)
            made.read_arrays = arrays
        return bounds


def step_rows(buffer: QpBuffer, rate_rows: np.ndarray | None, contact_rows: np.ndarray,
              margin: float) -> StepRows | None:
    """The native step writer, or None without the kernel (or without ``rate_rows``)."""
    if rate_rows is None or len(contact_rows) > MAX_SWING:
        return None
    library = loaded_kernel(kernel_source(__name__, "step_rows.c"), FALLBACK)
    return None if library is None else StepRows(library, buffer, rate_rows, contact_rows,
                                                 margin)
