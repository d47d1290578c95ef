"""One Gauss-Newton step of a frame as a value: its QP and the limit rows it left out.

:class:`FrameTasks` holds the solver's tasks and limits, made once per model; each frame sets
their targets. :func:`build_frame_problem` linearises them at a configuration into a
:class:`FrameProblem`, with the compiled step function (:mod:`.compiled`) when there is one,
else with the NumPy tasks (the same numbers, slower).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..model.human_model import HumanModel
from .active_set import LimitRows
from .compiled import CompiledKinematics, compiled_kinematics
from .compiled_sensed import SensedPoseSpec
from .configuration import Configuration
from .fast_math import add_to_diagonal, any_true, count_true
from .limits import ContactConstraint, FloorLimit, JointRangeLimit, VelocityLimit
from .limits.base import Equality, Inequality, empty_inequality
from .points_configuration import PointsConfiguration
from .qp import QpBuffer, QpProblem, build_qp
from .settings import SolverSettings
from .step_ranges import RateRows, evaluated_ranges
from .step_rows import StepRows, step_rows
from .tasks import (
    ChainShareTask,
    ColumnShapeTask,
    DampingTask,
    EvenChainTask,
    OrientationTask,
    PositionTask,
    PostureTask,
    Task,
)
from .tree_solve import tree_closed_form


@dataclass
class FrameProblem:
    """The QP of one step and its limit rows (:func:`.active_set.solve_with_active_set`)."""

    qp: QpProblem
    rows: LimitRows


@dataclass
class CompiledStep:
    """The compiled step function, the model geometry it is evaluated with, and its buffers.

    Attributes:
        kinematics: The compiled step function.
        geometry: The model's geometry input.
        buffer: Where each step's QP is built (overwritten by the next step).
        no_floor: The floor rows of a body without contact points (none).
        rate_rows: Where each row's structural nonzeros lie among those of the step's
            ``G_ranges`` (the rates of an angle to its joint's three tangent columns,
            :class:`.step_ranges.RateRows`); None when its rows do not hold three each.
        contacts_only: Whether the step function with only the contact points' and the
            root's sites (:attr:`.CompiledKinematics.function_points`) serves the steps that
            weigh no site target.
        rows: The native writer of the steps' QPs (:mod:`.step_rows`), or None (NumPy).
        excluded_weights: The last read-only persistence weights and whether they weigh a
            column beyond the step function (:func:`persistence_in_numpy`).
    """

    kinematics: CompiledKinematics
    geometry: np.ndarray
    buffer: QpBuffer
    no_floor: Inequality
    rate_rows: RateRows | None
    contacts_only: bool
    rows: StepRows | None = None
    excluded_weights: tuple[np.ndarray, bool] | None = None


@dataclass
class FrameTasks:
    """The solver's tasks and limits; each frame sets their targets.

    Attributes:
        orientation: Segment orientations (IMU).
        position: Site positions (UWB, markers).
        posture: The prior on joints the sensors leave open.
        even_chain: Unsensed columns (spine, neck) bend evenly.
        chain_share: ... and keep the last frame's share of their bend.
        shape: Site targets reached by the columns' share only (a head's tag).
        damping: Smoothness toward the previous frame.
        persistence: The bend of sensed joints kept (:class:`.sensed_pose.Persistence`).
        root: The pelvis position (aiding, flight, support).
        swing: Swing feet led by the correction.
        contact: Planted points held at their anchors.
        floor: Contact points above the floor.
        joint_range: Ranges of motion.
        velocity: Bounds on the step.
        contact_rows: (k,) rows of the contact points among the position task's sites.
    """

    orientation: OrientationTask
    position: PositionTask
    posture: PostureTask
    even_chain: EvenChainTask
    chain_share: ChainShareTask
    shape: ColumnShapeTask
    damping: DampingTask
    persistence: DampingTask
    root: PositionTask
    swing: PositionTask
    contact: ContactConstraint
    floor: FloorLimit
    joint_range: JointRangeLimit
    velocity: VelocityLimit
    contact_rows: np.ndarray

    @classmethod
    def create(cls, model: HumanModel, s: SolverSettings, contact_names: Sequence[str],
               persistence: DampingTask) -> FrameTasks:
        """The tasks and limits of ``model`` weighted by the settings ``s``."""
        segments, sites = model.segment_names, model.site_names
        nv = model.model.nv
        contact_ids = [model.site_frame_id(n) for n in contact_names]
        site_index = {n: i for i, n in enumerate(sites)}
        return cls(
            orientation=OrientationTask([model.segment_frame_id(n) for n in segments], segments,
                                        s.orientation),
            position=PositionTask([model.site_frame_id(n) for n in sites], sites, s.position),
            posture=PostureTask.from_joints(model.ball_joints, s.posture_joints, s.posture,
                                            s.posture_axes),
            even_chain=EvenChainTask(model.ball_joints, s.even_chains, s.even_chain, segments),
            chain_share=ChainShareTask(model.ball_joints, s.even_chains, s.chain_share, segments),
            shape=ColumnShapeTask([model.site_frame_id(n) for n in sites], sites,
                                  model.ball_joints, s.even_chains, nv, s.position),
            damping=DampingTask(tangent_vector(nv, s.smoothness_root_translation,
                                               s.smoothness_root_rotation, s.smoothness_joints)),
            persistence=persistence,
            root=PositionTask([model.segment_frame_id(segments[0])], [segments[0]]),
            swing=PositionTask(contact_ids, contact_names, s.swing),
            contact=ContactConstraint(contact_ids, contact_names,
                                      [model.sites[n].segment for n in contact_names]),
            floor=FloorLimit(contact_ids, s.floor_z),
            joint_range=JointRangeLimit(model.ball_joints, s.joint_range_margin_deg,
                                        s.joint_range_overshoot_deg, s.joint_range_settle_s),
            velocity=VelocityLimit(tangent_vector(nv, s.max_root_velocity,
                                                  s.max_root_angular_velocity,
                                                  s.max_joint_velocity)),
            contact_rows=np.array([site_index[n] for n in contact_names], dtype=int))

    def site_frames(self) -> list[int]:
        """The frames of the compiled step's points: the sites, then the root."""
        return list(self.position.frame_ids) + list(self.root.frame_ids)


def tangent_vector(nv: int, root_linear: float, root_angular: float,
                   joints: float) -> np.ndarray:
    """A tangent-space vector (nv,): root translation, root rotation, then every joint."""
    v = np.full(nv, joints, dtype=float)
    v[:3], v[3:6] = root_linear, root_angular
    return v


def compiled_step(model: HumanModel, tasks: FrameTasks,
                  sensed: SensedPoseSpec) -> CompiledStep | None:
    """The compiled step of ``model``; None when the model is beyond the code generator.

    None is not an error: the NumPy tasks give the same numbers, more slowly.
    """
    try:
        kinematics = compiled_kinematics(model.model, tasks.orientation.frame_ids,
                                         list(model.ball_joints.values()), tasks.site_frames(),
                                         sensed, tasks.even_chain.pairs,
                                         tasks.contact.frame_ids)
        nv = model.model.nv
        buffer, rates = QpBuffer(nv, tree_closed_form(model.model)), \
            rate_rows(kinematics.function.sparsity_out(7))
        return CompiledStep(kinematics, kinematics.geometry(model.model), buffer,
                            empty_inequality(nv), rates,
                            kinematics.point_rows is not None and kinematics.point_rows[:-1]
                            == tasks.contact_rows.tolist(),
                            step_rows(buffer, None if rates is None else rates.rows,
                                      tasks.contact_rows,
                                      tasks.joint_range.margin))
    except NotImplementedError:
        return None


def rate_rows(G_ranges: ca.Sparsity) -> RateRows | None:
    """Where each row's nonzeros lie among those of ``G_ranges``: (rows, 3) indices.

    None unless every row holds three (the rates of an angle to its joint's tangent columns).
    """
    rows = np.asarray(G_ranges.get_triplet()[0], dtype=int)
    if not np.array_equal(np.bincount(rows, minlength=G_ranges.size1()),
                          np.full(G_ranges.size1(), 3)):
        return None
    return RateRows(np.argsort(rows, kind="stable").reshape(-1, 3))


def step_configuration(model: HumanModel, tasks: FrameTasks,
                       compiled: CompiledStep | None) -> Configuration:
    """The configuration the solver steps, at the neutral pose.

    Its contact points come from the compiled points function (all of them in one call per
    configuration, :class:`.points_configuration.PointsConfiguration`) when there is one.
    """
    points = None if compiled is None else compiled.kinematics.points_function
    if compiled is None or points is None:
        return Configuration(model.model, model.neutral())
    return PointsConfiguration(model.model, model.neutral(), tasks.contact.frame_ids, points,
                               compiled.geometry)


def persistence_in_numpy(compiled: CompiledStep, weights: np.ndarray) -> bool:
    """Whether the persistence ``weights`` (nv,) weigh a column beyond the step function.

    Kept while the weights are the same read-only array (a frame's sensed joints').
    """
    kept = compiled.excluded_weights
    if kept is not None and kept[0] is weights:
        return kept[1]
    weighs = any_true(weights[compiled.kinematics.persistence_excluded])
    if not weights.flags.writeable:
        compiled.excluded_weights = (weights, weighs)
    return weighs


def build_frame_problem(conf: Configuration, tasks: FrameTasks, active: list[Task],
                        row_weights: tuple[np.ndarray, np.ndarray],
                        compiled: CompiledStep | None, levenberg_marquardt: float
                        ) -> FrameProblem:
    """The QP of one Gauss-Newton step at ``conf``.

    Args:
        conf: The configuration linearised at.
        tasks: The solver's tasks and limits, targets set.
        active: The tasks of this frame (the orientation, position, posture, even-chain,
            damping and persistence tasks, with the root or swing task when they are set).
        row_weights: Per-row weights of the orientation and the posture task.
        compiled: The compiled step, or None for the NumPy tasks.
        levenberg_marquardt: Damping of the step [1/rad^2].
    """
    previous = tasks.velocity.q_previous  # also the damping task's reference
    moved = None if previous is None else conf.difference(previous)
    nv = conf.model.nv
    limits = tasks.joint_range
    if compiled is None:
        bounds = tasks.velocity.bounds(conf, moved)
        ranges = limits.softened(limits.linearise(limits.angles(conf.q), None, nv))
        up, down = ranges.near(limits.margin)
        floor = tasks.floor.inequality(conf)
        qp = build_qp(conf, active, [ranges.inequality(up, down), floor],
                      [tasks.contact.equality(conf)], None, levenberg_marquardt)
        return FrameProblem(qp, LimitRows(ranges, up, down, floor, bounds))
    chain = tasks.even_chain.row_weights() if tasks.even_chain in active else None
    held = tasks.chain_share.q_previous
    share = (tasks.chain_share.row_weights(), held) \
        if held is not None and tasks.chain_share in active else None
    persistence = tasks.persistence
    reference = persistence.q_reference if persistence in active else None
    # the root's columns are beyond the compiled step: a task weighing them is summed in NumPy
    numpy_persistence = reference is not None and \
        persistence_in_numpy(compiled, persistence.weights)
    persist = (persistence.weights, reference) \
        if reference is not None and not numpy_persistence else None
    # the outputs (:mod:`.compiled`) this step reads: H, c, the sites and the ranges, read in
    # place (valid until the next evaluation, after this step's solve); the sites only when a
    # task or a limit weighs them (with contact points or site targets): otherwise from the
    # step function without them; without site targets, only the contact points and the root
    shape = tasks.shape in active and tasks.shape.has_targets()
    targets = shape or tasks.position.has_targets()
    sites = len(tasks.contact_rows) > 0 or tasks.root in active or targets
    few = compiled.contacts_only and not targets
    step = compiled.kinematics.evaluate(
        conf.q, tasks.orientation.targets, compiled.geometry, *row_weights,
        tasks.posture.R_reference, (limits.lower, limits.upper), chain, share, persist,
        None if few else sites)
    same = tasks.damping.q_reference is previous
    if compiled.rows is not None and not shape and not numpy_persistence:
        error = None if tasks.damping.q_reference is None else \
            moved if same else tasks.damping.compute_error(conf)
        # the move since the previous frame is the damping's error: the kernel bounds it too
        velocity = tasks.velocity if error is moved else None
        written = compiled.rows.write(step, compiled.kinematics, None if few else sites, tasks,
                                      active, error, levenberg_marquardt, velocity)
        if written is not None:
            qp, ranges, (up, down), floor_rows, bounds = written
            if velocity is None:
                bounds = tasks.velocity.bounds(conf, moved)
            return FrameProblem(qp, LimitRows(
                ranges, up, down,
                compiled.no_floor if floor_rows is None else floor_rows, bounds))
    bounds = tasks.velocity.bounds(conf, moved)
    if sites:
        P = step.output(5).reshape(-1, 3)
        J = step.output(6).reshape(-1, 3, nv)
    ranges = evaluated_ranges(step, compiled.rate_rows, limits)
    close = ranges.near(limits.margin)
    up, down = close[0], close[1]
    if few:  # the contact points' rows, then the root's
        Pc, Jc = P[:-1], J[:-1]
    elif len(tasks.contact_rows):
        Pc, Jc = P.take(tasks.contact_rows, axis=0), J.take(tasks.contact_rows, axis=0)
    n_floor, n_contact = 0, 0
    if len(tasks.contact_rows):
        n_floor, n_contact = len(tasks.floor.z_rows()), tasks.contact.count()
    n_up, below = count_true(up), count_true(close)
    # what assemble_qp makes of these blocks, built in one packed buffer (a step every frame)
    qp = compiled.buffer.views(below + n_floor, n_contact)
    if len(tasks.contact_rows):  # the floor's and the contacts' rows written in place
        floor = tasks.floor.rows(Pc, Jc, Inequality(qp.G[below:], qp.h[below:]))
        tasks.contact.rows(Pc, Jc, Equality(qp.A, qp.b))
    else:
        floor = compiled.no_floor
    H, c = qp.H, qp.c
    step.output_into(0, H)
    step.output_into(1, c[:, None])
    if sites and not few:  # (few: no site target)
        tasks.position.add_rows(P[:-1], J[:-1], H, c)
        if shape:
            tasks.shape.add_rows(P[:-1], J[:-1], H, c)
    if sites and tasks.root in active:
        tasks.root.add_rows(P[-1:], J[-1:], H, c)
    tasks.damping.add_objective(conf, H, c, moved if same else None)
    if numpy_persistence:
        persistence.add_objective(conf, H, c)
    if tasks.swing in active:
        tasks.swing.add_rows(Pc, Jc, H, c)
    add_to_diagonal(H, levenberg_marquardt)
    if n_up:  # the arrays' own compress: np.compress without its dispatch
        ranges.G.compress(up, axis=0, out=qp.G[:n_up])
    if below > n_up:
        np.negative(ranges.G.compress(down, axis=0, out=qp.G[n_up:below]),
                    out=qp.G[n_up:below])
    if below:  # both limits' rooms: room_up's then room_down's
        ranges.rooms.compress(close.ravel(), out=qp.h[:below])
    return FrameProblem(qp, LimitRows(ranges, up, down, floor, bounds))
