"""The robot's kinematics and tracking objective of one retargeting step in one compiled call.

Each Gauss-Newton step of :class:`~ikfusion.retarget.robot.RobotRetargeter` needs the tracking
objective (mapped links' orientations, feet pulled flat, scaled positions) and the placements
and Jacobians of the frames its constraints look at (feet, capsule links). Assembled from many
small NumPy operations and Pinocchio calls, that is most of a step's time; here it is one CasADi
function built from the blocks of the human solver's step (:mod:`ikfusion.ik.casadi_kinematics`,
natively compiled and cached by :mod:`ikfusion.ik.native`), evaluated once per configuration.

:class:`CompiledConfiguration` is a :class:`~ikfusion.ik.configuration.Configuration` whose
frame placements and Jacobians come from that call; frames it does not cover fall back to
Pinocchio. The objective is the one of the tasks' own ``add_objective`` (same residuals, same
weights) up to round-off.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from functools import lru_cache

import casadi as ca
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..ik.casadi_kinematics import (
    forward,
    frame_pose,
    geometry_vector,
    jacobian,
    symbolic_placements,
)
from ..ik.compiled import structure_key
from ..ik.configuration import Configuration
from ..ik.native import BoundFunction, cached_functions, column_major, native_functions
from ..ik.tasks import OrientationTask, PositionTask
from ..paths import module_source
from ..rotations_casadi import left_jacobian_inverse, log_so3
from .capsules import WITNESS_ENDS, CapsulePairs, closest_points_sx


class RobotStep:
    """The step function of one robot and one set of tracked frames.

    Inputs: ``q`` (nq), ``geometry`` (:func:`~ikfusion.ik.casadi_kinematics.geometry_vector`),
    the orientation targets ``R_world_target`` (k, 3, 3, column-major) with per-row weights
    ``w_orient`` (3k) [1/rad^2], and the position targets ``p_world_target`` (m, 3) [m] with
    per-row weights ``w_position`` (3m) [1/m^2]. Outputs: ``H`` (nv, nv) and ``c`` (nv) of
    ``1/2 dq^T H dq + c^T dq`` (orientation residuals ``log(R_world_frame R_world_target^T)``
    with Jacobians ``Jl^-1(e) J_angular``, position residuals ``p_world_frame - p_world_target``
    with linear Jacobians), and of each of ``frames``: ``R_world_frame`` (column-major),
    ``p_world_frame`` [m] and the LOCAL_WORLD_ALIGNED Jacobian (6, nv), linear rows first.
    With capsule pairs, also the input ``capsules`` (:meth:`CapsulePairs.geometry`) and the
    output ``d_witness`` (5k) [m], the exact distances of each pair's five witnesses
    (:meth:`CapsulePairs._witnesses`). With soles, also the input ``corners`` (4 per sole, in
    its link frame [m]) and the outputs ``z_corners`` (4s) [m], the corners' heights, and
    ``Jz_corners`` (4s, nv), their height Jacobians.

    :attr:`check_function` (``retarget_check``) gives only what tells whether a pose keeps the
    constraints, without any Jacobian: from ``q``, ``geometry``, ``capsules`` and ``corners``,
    the outputs ``p_frames``, ``d_witness`` and ``z_corners`` (the same expressions).
    :attr:`rows_functions` (``retarget_rows_<i>``, one per pair) give, from ``q``,
    ``geometry`` and ``capsules``, the keep-apart rows ``G_witness`` (5, nv),
    ``-n^T (J_p - J_q)``, of pair ``i``'s five witnesses: for all pairs, nearly half of the
    step's arithmetic, and only the pairs that come near need them.

    Args:
        model: The robot (free-flyer and revolute joints).
        orientation_frames: Frame ids with orientation targets, in target order.
        position_frames: Frame ids with position targets, in target order.
        frames: Frame ids whose placements and Jacobians are wanted.
        capsules: Capsule pairs whose witnesses are wanted.
        soles: Frame ids of the links carrying the sole corners (4 each).
        functions: The step, check and rows functions already built for this structure
            (loaded from the cache); built here when None.

    Raises:
        NotImplementedError: For joint types the graph does not cover.
    """

    def __init__(self, model: pin.Model, orientation_frames: Sequence[int],
                 position_frames: Sequence[int], frames: Sequence[int],
                 capsules: CapsulePairs | None = None, soles: Sequence[int] = (),
                 functions: Sequence[ca.Function] | None = None) -> None:
        pairs = capsules.frame_pairs if capsules is not None else []
        self.soles = list(soles)
        self.has_capsules = bool(pairs)
        self.frames = list(frames)
        self.orientation_frames = list(orientation_frames)
        self.position_frames = list(position_frames)
        self.geometry_frames = sorted(set(self.frames) | set(self.orientation_frames)
                                      | set(self.position_frames) | set(self.soles)
                                      | {f for p in pairs for f in p})
        self.warnings: list[str] = []
        self.function, self.check_function, *self.rows_functions = (
            functions if functions is not None else self._graph(model, pairs))
        self._rows_calls: dict[int, BoundFunction] = {}

    @staticmethod
    def function_names(pairs: int) -> list[str]:
        """Names of the step, check and rows functions with ``pairs`` capsule pairs."""
        return ["retarget_step", "retarget_check", *(f"retarget_rows_{i}" for i in range(pairs))]

    def _graph(self, model: pin.Model, pairs: list[tuple[int, int]]) -> list[ca.Function]:
        """The step, check and rows functions as CasADi graphs (see the class docstring)."""
        q = ca.SX.sym("q", model.nq)
        geometry = ca.SX.sym("geometry", 12 * (model.njoints - 1 + len(self.geometry_frames)))
        placements = symbolic_placements(geometry, model.njoints - 1, self.geometry_frames)
        rotations, translations, axes = forward(model, q, placements)
        k, m = len(self.orientation_frames), len(self.position_frames)
        R_target = ca.SX.sym("R_world_target", 9 * k)
        w_orient = ca.SX.sym("w_orient", 3 * k)
        p_target = ca.SX.sym("p_world_target", 3 * m)
        w_position = ca.SX.sym("w_position", 3 * m)

        errors, jacobians = [], []
        for n, fid in enumerate(self.orientation_frames):
            R, _ = frame_pose(model, fid, rotations, translations, placements)
            e, theta = log_so3(R @ ca.reshape(R_target[9 * n:9 * n + 9], 3, 3).T)
            errors.append(e)
            jacobians.append(left_jacobian_inverse(e, theta)
                             @ jacobian(model, fid, axes, translations, None)[3:, :])
        for n, fid in enumerate(self.position_frames):
            _, p = frame_pose(model, fid, rotations, translations, placements)
            errors.append(p - p_target[3 * n:3 * n + 3])
            jacobians.append(jacobian(model, fid, axes, translations, p)[:3, :])
        e_all = ca.vertcat(*errors) if errors else ca.SX(0, 1)
        J_all = ca.vertcat(*jacobians) if jacobians else ca.SX(0, model.nv)
        WJ = ca.diag(ca.vertcat(w_orient, w_position)) @ J_all
        H, c = J_all.T @ WJ, WJ.T @ e_all

        R_out, p_out, J_out = [], [], []
        for fid in self.frames:
            R, p = frame_pose(model, fid, rotations, translations, placements)
            R_out.append(ca.reshape(R, 9, 1))
            p_out.append(p)
            J_out.append(jacobian(model, fid, axes, translations, p))
        capsule_geometry = ca.SX.sym("capsules", 13 * len(pairs))
        d_witness: list[ca.SX] = []
        G_witness: list[list[ca.SX]] = []  # five rows per pair
        k = len(pairs)
        for i, frame_pair in enumerate(pairs):
            ends = []
            for side, fid in enumerate(frame_pair):
                R, o = frame_pose(model, fid, rotations, translations, placements)
                j = 6 * (side * k + i)
                ends.append([R @ capsule_geometry[j:j + 3] + o,
                             R @ capsule_geometry[j + 3:j + 6] + o])
            radius = capsule_geometry[12 * k + i]
            first_a, first_b, second_a, second_b = WITNESS_ENDS
            G_witness.append([])
            for n in range(5):
                p, q_ = closest_points_sx(ends[0][first_a[n]], ends[0][first_b[n]],
                                          ends[1][second_a[n]], ends[1][second_b[n]])
                gap = p - q_
                distance = ca.norm_2(gap)
                d_witness.append(distance - radius)
                J_gap = (jacobian(model, frame_pair[0], axes, translations, p)[:3, :]
                         - jacobian(model, frame_pair[1], axes, translations, q_)[:3, :])
                G_witness[-1].append(-(gap / ca.fmax(distance, 1e-9)).T @ J_gap)

        corners = ca.SX.sym("corners", 12 * len(self.soles))
        z_corners, Jz_corners = [], []
        for i, fid in enumerate(self.soles):
            R, o = frame_pose(model, fid, rotations, translations, placements)
            for n in range(4):
                point = R @ corners[12 * i + 3 * n:12 * i + 3 * n + 3] + o
                z_corners.append(point[2])
                Jz_corners.append(jacobian(model, fid, axes, translations, point)[2, :])

        p_frames = ca.vertcat(*p_out) if p_out else ca.SX(0, 1)
        d_all = ca.vertcat(*d_witness) if d_witness else ca.SX(0, 1)
        z_all = ca.vertcat(*z_corners) if z_corners else ca.SX(0, 1)
        check = ca.Function("retarget_check", [q, geometry, capsule_geometry, corners],
                            [p_frames, d_all, z_all],
                            ["q", "geometry", "capsules", "corners"],
                            ["p_frames", "d_witness", "z_corners"])
        rows = [ca.Function(name, [q, geometry, capsule_geometry], [ca.vertcat(*G)],
                            ["q", "geometry", "capsules"], ["G_witness"])
                for name, G in zip(self.function_names(len(pairs))[2:], G_witness)]
        return [ca.Function(
            "retarget_step",
            [q, geometry, R_target, w_orient, p_target, w_position, capsule_geometry, corners],
            [H, c, ca.vertcat(*R_out) if R_out else ca.SX(0, 1),
             p_frames,
             ca.vertcat(*J_out) if J_out else ca.SX(0, model.nv),
             d_all,
             z_all,
             ca.vertcat(*Jz_corners) if Jz_corners else ca.SX(0, model.nv)],
            ["q", "geometry", "R_world_target", "w_orient", "p_world_target", "w_position",
             "capsules", "corners"],
            ["H", "c", "R_frames", "p_frames", "J_frames", "d_witness", "z_corners",
             "Jz_corners"]), check, *rows]

    def geometry(self, model: pin.Model) -> np.ndarray:
        """The geometry input of ``model`` (its joint and frame placements)."""
        return geometry_vector(model, self.geometry_frames)

    def __call__(self, q: np.ndarray, geometry: np.ndarray, R_world_target: np.ndarray,
                 w_orient: np.ndarray, p_world_target: np.ndarray, w_position: np.ndarray,
                 capsules: np.ndarray, corners: np.ndarray) -> list[np.ndarray]:
        """The outputs as dense arrays, overwritten by the next call (copy to keep them).

        The inputs after ``q`` are sent again only when they are not the very arrays of the
        last call (the Gauss-Newton steps of one frame share them; callers never write into
        arrays they passed).
        """
        if not hasattr(self, "_call"):
            self._call = BoundFunction(self.function)
            self._sent: tuple[np.ndarray, ...] = ()
        rest = (geometry, R_world_target, w_orient, p_world_target, w_position, capsules,
                corners)
        if len(rest) == len(self._sent) and all(a is b for a, b in zip(rest, self._sent)):
            return self._call(q)
        self._sent = rest
        return self._call(q, geometry, column_major(R_world_target), w_orient,
                          p_world_target.reshape(-1), w_position, capsules, corners)

    def check(self, q: np.ndarray, geometry: np.ndarray, capsules: np.ndarray,
              corners: np.ndarray) -> list[np.ndarray]:
        """``p_frames``, ``d_witness`` and ``z_corners`` as dense arrays (overwritten next call)."""
        if not hasattr(self, "_check_call"):
            self._check_call = BoundFunction(self.check_function)
        return self._check_call(q, geometry, capsules, corners)

    def rows(self, pair: int, q: np.ndarray, geometry: np.ndarray,
             capsules: np.ndarray) -> np.ndarray:
        """Pair ``pair``'s ``G_witness`` (5, nv), dense (overwritten by the next call)."""
        call = self._rows_calls.get(pair)
        if call is None:
            call = self._rows_calls[pair] = BoundFunction(self.rows_functions[pair])
        return call(q, geometry, capsules)[0]


_BUILT: dict[str, RobotStep] = {}


def robot_step(model: pin.Model, orientation_frames: Sequence[int],
               position_frames: Sequence[int], frames: Sequence[int],
               capsules: CapsulePairs | None = None, soles: Sequence[int] = ()) -> RobotStep:
    """A (cached) :class:`RobotStep`, natively compiled when a C compiler exists.

    A failed compile leaves CasADi's virtual machine in place and says so in
    :attr:`RobotStep.warnings`.

    Raises:
        NotImplementedError: For joint types the graph does not cover.
    """
    pairs = capsules.frame_pairs if capsules is not None else []
    key = hashlib.sha256("|".join([
        _generator_fingerprint(), ",".join(map(str, orientation_frames)), str(list(soles)),
        ",".join(map(str, position_frames)), ",".join(map(str, frames)), str(pairs),
        structure_key(model, [*orientation_frames, *position_frames], [], frames),
    ]).encode()).hexdigest()[:20]
    built = _BUILT.get(key)
    if built is None:
        # no graph to build then
        cached = cached_functions(key, RobotStep.function_names(len(pairs)))
        built = RobotStep(model, orientation_frames, position_frames, frames, capsules, soles,
                          cached)
        if cached is None:
            native, problem = native_functions(
                [built.function, built.check_function, *built.rows_functions], key)
            if native is not None:
                built.function, built.check_function, *built.rows_functions = native
            if problem is not None:
                built.warnings.append(problem)
        _BUILT[key] = built
    return built


@lru_cache(maxsize=1)
def _generator_fingerprint() -> str:
    """SHA-256 of the modules whose code writes the graph (a changed graph is rebuilt)."""
    from . import capsules

    digest = hashlib.sha256()
    for module in (__name__, capsules.__name__):
        digest.update(module_source(module).read_bytes())
    return digest.hexdigest()


class CompiledConfiguration(Configuration):
    """A configuration whose step frames and tracking objective come from one compiled call.

    The orientation tasks (their frames in order) and the position task are read when the
    call runs (the first query after :meth:`update`), so their targets must be set before.

    Args:
        model: The robot.
        q: Configuration (nq,).
        step: The step function (built for the tasks' frames, in the same order).
        orientation_tasks: Tasks whose frames are ``step.orientation_frames``, in order.
        position_task: The task whose frames are ``step.position_frames``.
        capsules: The pairs the step was built with (their geometry is an input).
        corners: Sole corners (s, 4, 3) in their links' frames [m], of ``step.soles``.
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike, step: RobotStep,
                 orientation_tasks: Sequence[OrientationTask],
                 position_task: PositionTask, capsules: CapsulePairs | None = None,
                 corners: np.ndarray | None = None) -> None:
        self._step = step
        self._capsules = capsules.geometry() if capsules is not None else np.zeros(0)
        self._witnesses: np.ndarray | None = None
        self._rows: np.ndarray | None = None  # (5k, nv), filled pair by pair when asked
        self._rows_done: set[int] = set()
        self._corners = np.zeros(0) if corners is None else np.asarray(corners).reshape(-1)
        self._soles: tuple[np.ndarray, np.ndarray] = (np.zeros(0), np.zeros((0, model.nv)))
        self._inputs: tuple[list[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     np.ndarray] | None] = ([], None)
        self._geometry = step.geometry(model)
        self._orientation_tasks = list(orientation_tasks)
        self._position_task = position_task
        self._covered = {f: i for i, f in enumerate(step.frames)}
        self._objective: tuple[np.ndarray, np.ndarray] | None = None
        self._frames: tuple[np.ndarray, np.ndarray, np.ndarray] = (
            np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 6, model.nv)))
        self._checked: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._used_targets: tuple[np.ndarray, ...] = ()
        self._recheck_targets = False
        super().__init__(model, q)

    def update(self, q: npt.ArrayLike) -> None:
        """Set ``q``; the compiled call runs once, when first needed.

        The same ``q`` again keeps the kinematics (the objective too, unless the tasks' targets
        changed since).
        """
        if self._objective is not None and np.array_equal(q, self._q):
            self._recheck_targets = True
            return
        super().update(q)
        self._objective = None
        self._checked = None
        self._rows_done.clear()

    def _evaluate(self) -> tuple[np.ndarray, np.ndarray]:
        if self._objective is not None and self._recheck_targets:
            self._recheck_targets = False
            if self._targets() is not self._used_targets:
                self._objective = None
        if self._objective is None:
            self._used_targets = self._targets()
            orientations, w_orient, positions, w_position = self._used_targets
            H, c, R, p, J, d, z, Jz = self._step(
                self._q, self._geometry, orientations, w_orient, positions, w_position,
                self._capsules, self._corners)
            self._witnesses = d[:, 0].copy() if self._step.has_capsules else None
            self._soles = (z[:, 0].copy(), Jz.copy())
            # Placements are built when asked for (most steps only read a few of them).
            self._frames = (R.reshape(-1, 3, 3).transpose(0, 2, 1).copy(),  # column-major
                            p.reshape(-1, 3).copy(), J.reshape(-1, 6, J.shape[1]).copy())
            self._objective = H.copy(), c[:, 0].copy()
        return self._objective

    def _targets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The tasks' targets and per-row weights as the step's inputs (kept while unchanged).

        The tasks' ``set_targets`` replace their arrays (never write into them), so the
        arrays being the same objects as last time means unchanged targets.
        """
        position = self._position_task
        arrays = [x for t in self._orientation_tasks for x in (t.targets, t.weights)]
        arrays += [position.targets, position.information]
        known, inputs = self._inputs
        if inputs is None or len(arrays) != len(known) or any(
                a is not b for a, b in zip(arrays, known)):
            orientation = self._orientation_tasks
            inputs = (np.concatenate([t.targets for t in orientation]),
                      np.concatenate([t.row_weights() for t in orientation]),
                      position.targets, position.row_weights())
            self._inputs = (arrays, inputs)
        return inputs

    def constraint_values(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What tells whether this pose keeps the constraints.

        Returns the positions of the step's frames (F, 3) [m] (rows: :meth:`frame_row`), the
        witness distances (5k,) [m] and the sole corners' heights (4s,) [m]. From the full
        call when it ran at this pose, otherwise from the check function, which computes no
        objective and no Jacobian (a pose that is only checked, e.g. the last step of a
        frame, costs much less).
        """
        if self._objective is not None:
            witnesses = self._witnesses
            return (self._frames[1], np.zeros(0) if witnesses is None else witnesses,
                    self._soles[0])
        if self._checked is None:
            p, d, z = self._step.check(self._q, self._geometry, self._capsules, self._corners)
            self._checked = p.reshape(-1, 3).copy(), d[:, 0].copy(), z[:, 0].copy()
        return self._checked

    def frame_row(self, frame_id: int) -> int:
        """The row of ``frame_id`` in :meth:`constraint_values`' positions.

        Raises:
            KeyError: For a frame the step does not output.
        """
        return self._covered[frame_id]

    def sole_corners(self) -> tuple[np.ndarray, np.ndarray]:
        """Heights (4s,) [m] of the sole corners and their Jacobians (4s, nv), sole-major."""
        self._evaluate()
        return self._soles

    def tracking_objective(self) -> tuple[np.ndarray, np.ndarray]:
        """``H`` (nv, nv) and ``c`` (nv,) of the orientation and position tasks (new arrays)."""
        H, c = self._evaluate()
        return H.copy(), c.copy()

    def capsule_distances(self) -> np.ndarray | None:
        """Exact witness distances (5k,) [m], None without pairs.

        The five witnesses per pair of :class:`~ikfusion.retarget.capsules.CapsulePairs`.
        """
        self._evaluate()
        return self._witnesses

    def capsule_rows(self, pairs: Iterable[int]) -> np.ndarray | None:
        """The witnesses' keep-apart rows (5k, nv), None without pairs.

        Only the rows of ``pairs`` (pair indices) are computed (once per configuration);
        the other pairs' rows hold whatever an earlier configuration left there.
        """
        if not self._step.has_capsules:
            return None
        if self._rows is None:
            self._rows = np.zeros((5 * len(self._step.rows_functions), self.model.nv))
        for pair in pairs:
            if pair not in self._rows_done:
                self._rows[5 * pair:5 * pair + 5] = self._step.rows(
                    pair, self._q, self._geometry, self._capsules)
                self._rows_done.add(pair)
        return self._rows

    def placement(self, frame_id: int) -> pin.SE3:
        """``T_world_frame`` of one frame."""
        i = self._covered.get(frame_id)
        if i is None:
            return super().placement(frame_id)
        self._evaluate()
        T = self._placements.get(frame_id)
        if T is None:
            T = self._placements[frame_id] = pin.SE3(self._frames[0][i], self._frames[1][i])
        return T

    def frame_arrays(self, frame_id: int) -> tuple[np.ndarray, np.ndarray]:
        """``R_world_frame`` (3, 3) and ``p_world_frame`` (3,) [m] of one frame, as arrays."""
        i = self._covered.get(frame_id)
        if i is None:
            T = super().placement(frame_id)
            return T.rotation, T.translation
        self._evaluate()
        return self._frames[0][i], self._frames[1][i]

    def jacobian(self, frame_id: int) -> np.ndarray:
        """Frame Jacobian (6, nv), LOCAL_WORLD_ALIGNED (linear rows first)."""
        i = self._covered.get(frame_id)
        if i is None:
            return super().jacobian(frame_id)
        self._evaluate()
        return self._frames[2][i]
