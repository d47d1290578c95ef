"""The projection onto the contacts' minimum-norm steps in native code (``contact_projection.c``).

:func:`.projection.project_on_contacts` checks the planted points of a solved frame and, while
one is further than the tolerance from its anchor, takes a minimum-norm step on the contact
rows: a dozen NumPy and Pinocchio calls per step, on every frame. :class:`NativeProjection`
does that loop in one call of a small C kernel (compiled once and cached like
:mod:`.tree_solve`, :func:`ikfusion.native.kernel.loaded_kernel`) that evaluates the compiled points
function itself (through its pointer in the verified library, :func:`.native.compiled_library`)
and integrates as Pinocchio does for a free flyer and spherical joints. The same tests
(bit for bit: the same operations on the same positions), the steps to round-off (the sums of
``A A^T``, its Cholesky factor, ``A^T y`` and the integration in another order). Dependent
rows, numbers not finite or contacts not along the world axes go to the Python path, which
stays the reference (and the path without a C compiler or with ``IKFUSION_NO_COMPILE``).
"""

from __future__ import annotations

import ctypes

import numpy as np
import pinocchio as pin

from ..native.kernel import kernel_source, loaded_kernel
from .configuration import Configuration
from .kernel_arguments import ProjectionArguments
from .limits import ContactConstraint, FloorLimit
from .native import compiled_library
from .points_configuration import PointsConfiguration

#: The kernel's answers (``contact_projection.c``).
HELD, TO_QP, TO_PYTHON = 0, 1, 2
#: What is used when the kernel cannot be compiled (the end of the warning).
FALLBACK = "NumPy and Pinocchio project the frames onto their contacts instead"


def _address(a: np.ndarray) -> int:
    return int(a.ctypes.data)


def ball_joints(model: pin.Model) -> tuple[np.ndarray, np.ndarray] | None:
    """(first q index, first tangent index) of each spherical joint, int32.

    None unless the first joint is a free flyer at ``q[0:7]``, ``v[0:6]`` and every other is
    spherical (the joints the kernel integrates).
    """
    joints = list(model.joints)[1:]
    if not joints or joints[0].shortname() != "JointModelFreeFlyer" or joints[0].idx_q != 0 \
            or joints[0].idx_v != 0:
        return None
    if any(j.shortname() != "JointModelSpherical" for j in joints[1:]):
        return None
    return (np.array([j.idx_q for j in joints[1:]], dtype=np.intc),
            np.array([j.idx_v for j in joints[1:]], dtype=np.intc))


class NativeProjection:
    """The kernel on one :class:`.PointsConfiguration` (made by :func:`native_projection`).

    Args:
        library: The loaded kernel.
        points: The compiled points function's library (ctypes).
        conf: The configuration whose points function it evaluates, writing into its buffers.
        balls: :func:`ball_joints` of the model.
    """

    def __init__(self, library: ctypes.CDLL, points: ctypes.CDLL, conf: PointsConfiguration,
                 balls: tuple[np.ndarray, np.ndarray]) -> None:
        function, call = conf.points_function, conf.points_call
        name = function.name()
        sizes = [ctypes.c_longlong() for _ in range(4)]
        getattr(points, f"{name}_work")(*[ctypes.byref(s) for s in sizes])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sizes)
        self._arg = (ctypes.c_void_p * max(n_arg, 2))()
        self._res = (ctypes.c_void_p * max(n_res, 2))()
        self._arg[1] = _address(call.input_slot(1))  # the geometry, kept in its slot
        self._res[0] = _address(call.nonzeros(0))  # the points function's own output buffers:
        self._res[1] = _address(call.nonzeros(1))  # the configuration reads them after a call
        self._iw = np.zeros(n_iw, dtype=np.int64)
        self._w = np.zeros(n_w)
        rows, cols = (np.array(v, dtype=np.intc) for v in function.sparsity_out(1).get_triplet())
        model = conf.model
        n = len(conf.point_frames)
        self._keep = [rows, cols, *balls]
        self.J = np.zeros((3 * n, model.nv))
        self.active = np.zeros(n, dtype=bool)  # (unsigned char in the kernel)
        self.free_z = np.zeros(n, dtype=bool)
        self.anchors = np.zeros((n, 3))
        self.enabled = np.zeros(n, dtype=bool)
        self.q = np.zeros(model.nq)
        self._next = np.zeros(model.nq)
        self._rows = np.zeros(3 * n, dtype=np.intc)
        self._S = np.zeros((3 * n, 3 * n))
        self._y = np.zeros(3 * n)
        self._dq = np.zeros(model.nv)
        function_pointer = ctypes.cast(getattr(points, name), ctypes.c_void_p).value
        self.plan = ProjectionArguments(
            function_pointer, ctypes.addressof(self._arg), ctypes.addressof(self._res),
            _address(self._iw), _address(self._w), _address(rows), _address(cols), len(rows),
            _address(self.J), n, model.nq, model.nv, len(balls[0]), _address(balls[0]),
            _address(balls[1]), _address(self.active), _address(self.free_z),
            _address(self.anchors), _address(self.enabled), 0.0, 0.0, 0, _address(self.q),
            _address(self._rows), _address(self._S), _address(self._y), _address(self._dq), 0, 0)
        self._kernel = library.ik_project_contacts
        self._kernel.restype = ctypes.c_int
        self._kernel.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        self._args = (ctypes.addressof(self.plan), _address(self._next))
        self.conf = conf

    def project(self, contact: ContactConstraint, floor: FloorLimit, tolerance: float,
                max_steps: int) -> int:
        """The minimum-norm loop from the configuration's ``q`` (contacts along world axes).

        Returns:
            :data:`HELD` (the configuration set to the projected ``q``, its points evaluated
            there), :data:`TO_QP` or :data:`TO_PYTHON` (the configuration at its ``q``,
            unchanged, its points evaluated again when asked for). With :data:`TO_QP`,
            ``plan.floor_crossed``: the first step crossed a floor row linearised at ``q``
            (by far more than round-off), so the QPs' closed-form try would fail.
        """
        conf, plan = self.conf, self.plan
        # copied by slice assignment (np.copyto's dispatch cost 0.5 us a call), the masks from
        # bool into bool (the kernel reads their bytes, 0 or 1)
        self.q[:] = conf.q
        self.active[:] = contact.active
        self.free_z[:] = contact.free_z
        self.anchors[:] = contact.anchors
        self.enabled[:] = floor.enabled
        plan.floor_z, plan.tolerance, plan.max_steps = floor.floor_z, tolerance, max_steps
        answer = int(self._kernel(*self._args))
        if answer == HELD:  # its buffers hold the points at the projected q
            if plan.steps:
                conf.set_evaluated(self.q)
            else:  # (half the frames of a walk) q not moved: the configuration kept
                conf.points_evaluated()
        else:
            conf.update(conf.q)  # the kernel overwrote the buffers of the points at q
        return answer


def native_projection(conf: Configuration, contact: ContactConstraint
                      ) -> NativeProjection | None:
    """The native minimum-norm loop of ``conf``; None for the Python path.

    None without a compiled points function in a verified library, for a model with joints
    other than a free flyer and spherical ones, for contact frames other than the
    configuration's points, or without the kernel (no C compiler, ``IKFUSION_NO_COMPILE``).
    """
    if not isinstance(conf, PointsConfiguration) or \
            tuple(contact.frame_ids) != conf.point_frames:
        return None
    points = compiled_library(conf.points_function)
    balls = ball_joints(conf.model)
    if points is None or balls is None:
        return None
    library = loaded_kernel(kernel_source(__name__, "contact_projection.c"), FALLBACK)
    return None if library is None else NativeProjection(library, points, conf, balls)
