"""The argument structures of the solver's native kernels, as ctypes declares them.

Each class mirrors one ``struct`` of a kernel's C source (``ikfusion/ik/*.c``), field for field
and in order: a kernel reads its arguments from one such structure, whose address its wrapper
passes. They live here, apart from their wrappers, because mypyc
(:mod:`ikfusion.native.typed_modules`) cannot compile a ``ctypes.Structure`` subclass: this
module stays Python, the wrappers compile. Pointers are addresses (``c_void_p``; None: no
array), counts C ``int`` or ``long long``, numbers ``double``.
"""

from __future__ import annotations

import ctypes

_P, _I, _D, _L = ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_longlong


class ClockArguments(ctypes.Structure):
    """The contact clocks' arguments (``struct clocks`` of ``contact_clocks.c``)."""

    _fields_ = [("released", _P), ("age", _P), ("anchors", _P), ("out", _P), ("was", _L),
                ("k", _I), ("settle", _I), ("step", _D), ("drop", _D), ("floor_z", _D),
                ("changed", _I)]


class SensedArguments(ctypes.Structure):
    """The sensed contact evidence's arguments (``struct sensed`` of ``sensed_evidence.c``)."""

    _fields_ = [("p_new", _P), ("pitch_new", _P), ("p_old", _P), ("pitch_old", _P),
                ("out", _P), ("rest", _P), ("heels", _P), ("toes", _P), ("n_rest", _I),
                ("n_heels", _I), ("n_toes", _I), ("k", _I), ("a", _D), ("b", _D), ("dt", _D),
                ("far", _D), ("enter", _D), ("leave", _D), ("tilt", _D), ("far_bits", _L),
                ("low", _L), ("high", _L), ("tilted", _L)]


class StepPoints(ctypes.Structure):
    """A point task of a step's QP (``struct points`` of ``step_rows.c``)."""

    _fields_ = [("on", _I), ("count", _I), ("scale", _D), ("weight", _P), ("targets", _P)]


class StepPlan(ctypes.Structure):
    """One step function's QP rows (``struct step_rows`` of ``step_rows.c``)."""

    _fields_ = [("H_nz", _P), ("H_flat", _P), ("H_nnz", _I), ("c_nz", _P), ("c_flat", _P),
                ("c_nnz", _I), ("P", _P),
                ("J_nz", _P), ("J_ptr", _P), ("J_col", _P), ("J_at", _P),
                ("G_nz", _P), ("G_flat", _P), ("G_nnz", _I), ("G", _P), ("rate_rows", _P),
                ("rooms_raw", _P), ("contact_site", _P), ("nv", _I), ("angles", _I),
                ("root_site", _I), ("rooms", _P), ("close", _P), ("packed", _P), ("work", _P),
                ("n_up", _I), ("wall_room", _P), ("margin", _D), ("floor_rows", _P),
                ("n_floor", _I), ("floor_z", _D), ("held_rows", _P), ("n_held", _I),
                ("anchors", _P), ("root_on", _I), ("root_weight", _D), ("root_target", _P),
                ("site_task", StepPoints), ("swing", StepPoints), ("damping", _P), ("moved", _P),
                ("levenberg_marquardt", _D), ("span", _P), ("bounds", _P)]


class TreePlan(ctypes.Structure):
    """The tree solve's state from call to call (``struct plan`` of ``tree_solve.c``)."""

    _fields_ = [("ptr", _P), ("anc", _P), ("off", _P), ("x", _P), ("work", _P),
                ("dependent_rows", _D), ("n", _I), ("n_off", _I)]


class ActiveRows(ctypes.Structure):
    """The limit rows left out of a step's QP (``struct active`` of ``tree_solve.c``)."""

    _fields_ = [("G", _P), ("rooms", _P), ("bounds", _P), ("up", _P), ("down", _P),
                ("tolerance", _D), ("angles", _I), ("has_bounds", _I)]


class WallArguments(ctypes.Structure):
    """The soft wall's sink arguments (``struct wall`` of ``wall_sink.c``)."""

    _fields_ = [("now", _P), ("before", _P), ("limit", _P), ("sunk", _P), ("grow", _D),
                ("drift", _D), ("count", _I)]


class ProjectionArguments(ctypes.Structure):
    """The projection onto the contacts (``struct projection`` of ``contact_projection.c``)."""

    _fields_ = [("points", _P), ("arg", _P), ("res", _P), ("iw", _P), ("w", _P),
                ("J_row", _P), ("J_col", _P), ("J_nnz", _I), ("J", _P),
                ("n_points", _I), ("nq", _I), ("nv", _I), ("n_balls", _I), ("ball_q", _P),
                ("ball_v", _P), ("active", _P), ("free_z", _P), ("anchors", _P),
                ("enabled", _P), ("floor_z", _D), ("tolerance", _D), ("max_steps", _I),
                ("q", _P), ("rows", _P), ("S", _P), ("y", _P), ("dq", _P), ("steps", _I),
                ("floor_crossed", _I)]
