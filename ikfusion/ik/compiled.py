"""Kinematics and task residuals of one Gauss-Newton step as a single CasADi function.

The forward kinematics of the Pinocchio model and every residual with its Jacobian, written
once as a CasADi ``SX`` graph evaluated in one call (from many small NumPy operations, a step
would cost milliseconds). The graph follows the Pinocchio model exactly (same joint placements
and joint types); the tests compare it with Pinocchio's own kinematics.

Tangent steps follow Pinocchio (a free-flyer moves by ``M exp(v)`` in its local frame, a
spherical joint by ``R exp(w)``, a revolute joint adds to its angle); only first derivatives at
``dq = 0`` are needed, so the graph uses ``R (I + [w]x)`` (the same value and Jacobian there).

Inputs besides ``q``, the targets and the geometry: per-row weights of the orientation
residuals ``w_orient`` (3k), of the posture residuals ``w_posture`` (3j), of the even-chain
pairs ``w_chain`` and of the chain-share pairs ``w_share`` (3 per pair) [1/rad^2] with the
configuration ``q_previous`` whose differences the share holds, the persistence task's weights
``w_persist`` (nv) and reference ``q_persist`` (nq) (:mod:`.compiled_joint_tasks`), and the
posture task's reference joint rotations ``R_reference`` (j, 3, 3). The SO(3) maps (log,
``Jl^-1``, quaternions, Euler angles) are those of :mod:`ikfusion.rotations_casadi`, the twin of
:mod:`ikfusion.rotations` that the NumPy tasks use, with one epsilon policy. Outputs (``k``
tracked segments, ``j`` ball joints, ``m`` sites), all in the world frame:

* ``H`` (nv, nv) and ``c`` (nv): the Gauss-Newton objective ``1/2 dq^T H dq + c^T dq`` of the
  orientation, posture, even-chain, chain-share and persistence tasks, ``H = sum J^T W J`` and
  ``c = sum J^T W e``, with ``e_orient = log(R_world_segment R_world_target^T)``,
  ``J_orient = Jl^-1(e) J_angular``, ``e_posture = log(R_reference^T R_parent_child)`` and
  ``J_posture`` = ``Jr^-1(e)`` on each joint's columns (as
  :class:`ikfusion.ik.tasks.PostureTask`), ``e_chain = log(R_i) - log(R_j)`` per pair of
  neighbouring joints with ``[Jr^-1(e_i), -Jr^-1(e_j)]`` on their columns (as
  :class:`ikfusion.ik.tasks.EvenChainTask`; the chain-share pairs want the difference of
  ``q_previous``), and the persistence's ``w_persist (q ⊖ q_persist)`` on the diagonal; the
  orientation part is summed along the kinematic tree
  (:func:`.casadi_kinematics.angular_objective`); the function outputs ``H``'s lower triangle
  only (:data:`MIRRORED`), which its readers mirror: :class:`.bound_function.BoundFunction`
  made with ``mirrored`` and :mod:`.step_rows` (the same numbers in both triangles, half the
  writes in the generated code);
* ``e_orient`` (3k) [rad];
* ``angles`` (3j): anatomical angles [rad] in sequence order; ``E_inv`` (3j, 3): their rates
  per unit joint tangent step;
* ``p_sites`` (3m) [m] and ``J_sites`` (3m, nv);
* ``G_ranges`` (3j, nv), ``room_up`` and ``room_down`` (3j) [rad]: the ranges of motion (inputs
  ``lower``, ``upper``) linearised (:mod:`.compiled_ranges`).

The pieces repeated per segment, per ball joint and per pair of joints are CasADi functions the
graph calls (:mod:`.compiled_blocks`): one body each in the generated C code, a step function a
third the size of the same expressions written inline (its code is fetched from memory on every
call) with the same numbers. The graph holds the model's *structure* only
(:mod:`.casadi_kinematics`); joint and frame placements are an input, so bodies of every size
share one function. With a C compiler it is compiled once (:mod:`.native`), ten times faster
than CasADi's virtual machine (the fallback; a failed build says so on stderr and becomes a
warning of the solve).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pinocchio as pin

from ..model.ball_joints import BallJoint
from .bound_function import BoundFunction
from .casadi_kinematics import (
    angular_objective,
    angular_triples,
    forward,
    geometry_vector,
    orientation_terms,
    symbolic_placements,
)
from .compiled_blocks import ball_joint_pieces
from .compiled_inputs import SlotInputs
from .compiled_joint_tasks import chain_objective, joint_columns, persistence_objective
from .compiled_key import structure_key as structure_key  # re-exported (retarget)
from .compiled_points import point_kinematics, point_rows, points_function, rows_only
from .compiled_ranges import range_matrix
from .compiled_sensed import SensedPoseSpec, sensed_pose_function
from .native import cached_functions, native_functions


class CompiledKinematics:
    """The residuals of one IK step for a fixed set of segments, ball joints and sites.

    Args:
        model: Pinocchio model (free-flyer, spherical and revolute joints).
        segment_frames: Frame ids whose orientations are tracked (targets are inputs).
        ball_joints: Ball joints for the posture prior and the ranges of motion.
        site_frames: Frame ids whose positions are needed (sites, contact points, the root).
        sensed: Also build :attr:`sensed_function` (the sensed configuration and positions of
            points there).
        chain_pairs: The neighbouring joints of :class:`.tasks.EvenChainTask` (its
            ``pairs``), whose objective joins ``H`` and ``c`` weighted by the input ``w_chain``.
        points: Frame ids of :attr:`points_function` (their positions and linear Jacobians,
            :mod:`.compiled_points`); none when empty.
        loaded: The functions already built (as :meth:`functions` lists them, loaded from a
            cached library): the graph is then not built again.

    Raises:
        NotImplementedError: For joint types the graph does not cover.
    """

    #: The names of the step function, the sensed-pose function, the points function, the
    #: step function without the sites (:attr:`function_no_sites`) and the one with only the
    #: points and the root (:attr:`function_points`).
    FUNCTION_NAMES: ClassVar[tuple[str, ...]] = (
        "ik_step_objective", "ik_sensed_pose", "ik_points", "ik_step_no_sites", "ik_step_points")

    def __init__(self, model: pin.Model, segment_frames: Sequence[int],
                 ball_joints: Sequence[BallJoint], site_frames: Sequence[int],
                 sensed: SensedPoseSpec | None = None,
                 loaded: Sequence[ca.Function] | None = None,
                 chain_pairs: Sequence[tuple[BallJoint, BallJoint]] = (),
                 points: Sequence[int] = ()) -> None:
        self.nv = model.nv
        self.warnings: list[str] = []  # e.g. a failed native compile (see compiled_kinematics)
        self.segment_frames = list(segment_frames)
        self.site_frames = list(site_frames)
        self.point_frames = list(points)
        frames = sorted(set(self.segment_frames) | set(self.site_frames)
                        | set(sensed.points if sensed else ()) | set(self.point_frames))
        self._geometry_frames = frames
        self._no_chain = np.zeros(3 * len(chain_pairs))
        self._no_persist = np.zeros(model.nv)
        for unset in (self._no_chain, self._no_persist):  # kept in their slots (read-only)
            unset.setflags(write=False)
        #: Tangent columns the persistence twin leaves out (the root's): its weights must be 0.
        self.persistence_excluded = np.flatnonzero(~joint_columns(model))
        self.sensed_function: ca.Function | None = None
        self.points_function: ca.Function | None = None
        #: The sites of :attr:`function_points`: the points' rows, then the root's (the last).
        self.point_rows = point_rows(self.site_frames, self.point_frames)
        self.function_points: ca.Function | None = None
        self._steps: dict[bool | None, SlotInputs] = {}
        self._no_limits: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        if loaded is not None:
            self.use_functions(loaded)
            return
        q = ca.SX.sym("q", model.nq)
        targets = ca.SX.sym("R_world_target", 9 * len(segment_frames))
        geometry = ca.SX.sym("geometry", 12 * (model.njoints - 1 + len(frames)))
        placements = symbolic_placements(geometry, model.njoints - 1, frames)
        rotations, translations, axes = forward(model, q, placements)
        self.sensed_function = (None if sensed is None else
                                sensed_pose_function(model, sensed, self.FUNCTION_NAMES[1], q,
                                                     targets, geometry, placements))
        self.points_function = (None if not self.point_frames else
                                points_function(model, self.point_frames, self.FUNCTION_NAMES[2],
                                                q, geometry, placements, rotations,
                                                translations, axes))

        w_orient = ca.SX.sym("w_orient", 3 * len(segment_frames))
        e_orient, K_orient, g_orient, dofs = orientation_terms(
            model, segment_frames, targets, w_orient, (rotations, translations, axes), placements)

        references = ca.SX.sym("R_reference", 9 * len(ball_joints))
        lower = ca.SX.sym("lower", 3 * len(ball_joints))
        upper = ca.SX.sym("upper", 3 * len(ball_joints))
        joint_pieces = ball_joint_pieces()  # one body per Euler sequence, called per joint
        e_post, J_post, angles, E_inv, G_blocks, up, down = [], [], [], [], [], [], []
        for n, joint in enumerate(ball_joints):
            iq, rows = joint.idx_q, slice(3 * n, 3 * n + 3)
            e, Jr_inv, a, rates, G, room_up, room_down = joint_pieces(
                joint, q[iq:iq + 4], ca.reshape(references[9 * n:9 * n + 9], 3, 3), lower[rows],
                upper[rows])
            e_post.append(e)
            block = ca.SX(3, model.nv)
            block[:, joint.idx_v:joint.idx_v + 3] = Jr_inv
            J_post.append(block)
            angles.append(a)
            E_inv.append(rates)
            G_blocks.append(G)
            up.append(room_up)
            down.append(room_down)

        p_sites, J_sites = point_kinematics(model, site_frames, rotations, translations,
                                            placements, axes)

        def stack(parts: list[ca.SX], cols: int) -> ca.SX:
            return ca.vertcat(*parts) if parts else ca.SX(0, cols)
        G_ranges = range_matrix(G_blocks, [j.idx_v for j in ball_joints], model.nv)
        room_up, room_down = stack(up, 1), stack(down, 1)
        w_posture = ca.SX.sym("w_posture", 3 * len(ball_joints))
        w_chain = ca.SX.sym("w_chain", 3 * len(chain_pairs))
        w_share = ca.SX.sym("w_share", 3 * len(chain_pairs))
        q_previous = ca.SX.sym("q_previous", model.nq)
        w_persist = ca.SX.sym("w_persist", model.nv)
        q_persist = ca.SX.sym("q_persist", model.nq)
        H, c = angular_objective(K_orient, g_orient, dofs, axes, model.nv,
                                angular_triples(model))
        e_post_all, J_post_all = stack(e_post, 1), stack(J_post, model.nv)
        WJ = ca.diag(w_posture) @ J_post_all
        H += J_post_all.T @ WJ
        c += WJ.T @ e_post_all
        H_chain, c_chain = chain_objective(q, q_previous, chain_pairs, w_chain, w_share, model.nv)
        H_persist, c_persist = persistence_objective(model, q, q_persist, w_persist)
        H += H_chain + ca.diag(H_persist)
        c += c_chain + c_persist
        # H is symmetric: only its lower triangle is an output (the graph of a product holds
        # both, each its own sums); its readers mirror it (one write per entry in the code)
        H = ca.tril(H)
        inputs = [q, targets, geometry, w_orient, w_posture, references, lower, upper, w_chain,
                  w_share, q_previous, w_persist, q_persist]
        outputs = [H, c, stack(e_orient, 1), stack(angles, 1), stack(E_inv, 3),
                   stack(p_sites, 1), stack(J_sites, model.nv), G_ranges, room_up, room_down]
        names = ("q R_world_target geometry w_orient w_posture R_reference lower upper w_chain "
                 "w_share q_previous w_persist q_persist".split(),
                 "H c e_orient angles E_inv p_sites J_sites G_ranges room_up room_down".split())
        # common subexpressions once ("cse"): the same operations on the same numbers (the same
        # results bit for bit) in 9 % fewer instructions; without the sites (their outputs
        # structural zeros) a step weighing none (orientations alone) runs a fifth fewer
        self.function, self.function_no_sites = (ca.Function(
            self.FUNCTION_NAMES[n], inputs, [ca.SX(*o.shape) if n and i in (5, 6) else o
                                             for i, o in enumerate(outputs)], *names,
            {"cse": True}) for n in (0, 3))
        if self.point_rows is not None:
            self.function_points = ca.Function(self.FUNCTION_NAMES[4], inputs,
                                               rows_only(outputs, self.point_rows), *names,
                                               {"cse": True})

    def functions(self) -> list[ca.Function]:
        """The functions built, in :attr:`FUNCTION_NAMES` order."""
        return [f for f in (self.function, self.sensed_function, self.points_function,
                            self.function_no_sites, self.function_points) if f is not None]

    def use_functions(self, functions: Sequence[ca.Function]) -> None:
        """Evaluate with ``functions`` (e.g. natively compiled), matched by name."""
        by_name = {f.name(): f for f in functions}
        self.function = by_name[self.FUNCTION_NAMES[0]]
        self.sensed_function = by_name.get(self.FUNCTION_NAMES[1])
        self.points_function = by_name.get(self.FUNCTION_NAMES[2])
        self.function_no_sites = by_name[self.FUNCTION_NAMES[3]]
        self.function_points = by_name.get(self.FUNCTION_NAMES[4])
        self._steps = {}

    def geometry(self, model: pin.Model) -> np.ndarray:
        """The geometry input of ``model`` (joint and frame placements; column-major R, then p).

        Bodies of another size share the compiled structure and only change this vector.
        """
        geometry = geometry_vector(model, self._geometry_frames)
        geometry.setflags(write=False)  # the same numbers while the same array (kept in a slot)
        return geometry

    def __call__(self, *inputs: Any, **options: Any) -> list[np.ndarray]:
        """Every output of :meth:`evaluate` (same arguments), dense, overwritten by the next."""
        step = self.evaluate(*inputs, **options)
        return [step.output(i) for i in range(self.function.n_out())]

    def evaluate(self, q: np.ndarray, R_world_target: np.ndarray, geometry: np.ndarray,
                 w_orient: np.ndarray, w_posture: np.ndarray, R_reference: np.ndarray,
                 limits: tuple[np.ndarray, np.ndarray] | None = None,
                 w_chain: np.ndarray | None = None,
                 share: tuple[np.ndarray, np.ndarray] | None = None,
                 persist: tuple[np.ndarray, np.ndarray] | None = None,
                 sites: bool | None = True) -> BoundFunction:
        """Evaluate the step function at ``q`` (the inputs that changed written into their slots).

        Args:
            q: Configuration (nq,).
            R_world_target: Segment targets (k, 3, 3).
            geometry: Joint and frame placements (:meth:`geometry`).
            w_orient: Per-row orientation weights (3k,) [1/rad^2].
            w_posture: Per-row posture weights (3j,) [1/rad^2].
            R_reference: The posture task's reference joint rotations (j, 3, 3).
            limits: Ranges of motion (lower, upper) (j, 3) [rad]; zero ranges when omitted.
            w_chain: Even-chain per-row weights (3 pairs,) [1/rad^2] (zero when omitted).
            share: The chain-share task's per-row weights (3 pairs,) [1/rad^2] and the
                configuration whose differences it holds (nq,); off when omitted.
            persist: Persistence weights (nv,) [1/rad^2] (0 on :attr:`persistence_excluded`)
                and reference (nq,); off when omitted.
            sites: Whether ``p_sites`` and ``J_sites`` are wanted (else they are zeros, from
                :attr:`function_no_sites`); None: only the rows :attr:`point_rows`, from
                :attr:`function_points` (all of them when there is none).

        Returns:
            The evaluated function: ``output(i)`` in the module docstring's order, overwritten
            by the next evaluation (only the outputs read are made dense).
        """
        step = self._steps.get(sites)
        if step is None:
            step = self._steps[sites] = self._slot_inputs(sites)
        if limits is None:
            limits = self._no_limits.get(len(w_posture)) or self._zero_limits(len(w_posture))
        w_share, q_previous = (self._no_chain, q) if share is None else share
        w_persist, q_persist = (self._no_persist, q) if persist is None else persist
        return step.set((q, R_world_target, geometry, w_orient, w_posture, R_reference,
                         limits[0], limits[1], self._no_chain if w_chain is None else w_chain,
                         w_share, q_previous, w_persist, q_persist))

    def _slot_inputs(self, sites: bool | None) -> SlotInputs:
        """The inputs of the step function that ``sites`` chooses (:meth:`evaluate`)."""
        chosen = self.function_no_sites if sites is False else \
            self.function_points if sites is None else None
        # q, R_world_target, q_previous and q_persist are new at every step; the rotations
        # (R_world_target, R_reference) go in as column-major vectors; the ranges' (j, 3)
        return SlotInputs(BoundFunction(self.function if chosen is None else chosen, MIRRORED),
                          (0, 1, 10, 12), (1, 5), (6, 7))

    def _zero_limits(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """Zero ranges (lower, upper) of ``size`` angles (read-only, kept)."""
        zeros = np.zeros(size)
        zeros.setflags(write=False)
        made = self._no_limits[size] = (zeros, zeros)
        return made


#: The outputs of the step functions that hold only their lower triangle (``H``).
MIRRORED = (0,)

_BUILT: dict[str, CompiledKinematics] = {}


def compiled_kinematics(model: pin.Model, segment_frames: Sequence[int],
                        ball_joints: Sequence[BallJoint], site_frames: Sequence[int],
                        sensed: SensedPoseSpec | None = None,
                        chain_pairs: Sequence[tuple[BallJoint, BallJoint]] = (),
                        points: Sequence[int] = ()) -> CompiledKinematics:
    """A (cached) :class:`CompiledKinematics`, natively compiled when a C compiler exists.

    A library already built and verified is loaded without building the CasADi graphs again
    (that takes longer than loading). A failed compile leaves CasADi's virtual machine in place
    and says so in :attr:`CompiledKinematics.warnings` (and on stderr).
    """
    key = structure_key(model, segment_frames, ball_joints, site_frames, sensed, chain_pairs,
                        points)
    built = _BUILT.get(key)
    if built is None:
        names = [n for n, wanted in zip(CompiledKinematics.FUNCTION_NAMES,
                                        (True, sensed is not None, len(points) > 0, True,
                                         point_rows(site_frames, points) is not None))
                 if wanted]
        cached = cached_functions(key, names)
        if cached is not None:
            built = _BUILT[key] = CompiledKinematics(model, segment_frames, ball_joints,
                                                     site_frames, sensed, cached, chain_pairs,
                                                     points)
            return built
        built = CompiledKinematics(model, segment_frames, ball_joints, site_frames, sensed,
                                   chain_pairs=chain_pairs, points=points)
        native, problem = native_functions(built.functions(), key)
        if native is not None:
            built.use_functions(native)
        if problem is not None:
            built.warnings.append(problem)
        _BUILT[key] = built
    return built
