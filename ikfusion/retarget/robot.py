"""Retargeting human motion onto a humanoid robot, frame by frame, as the solver's QP.

Per frame, warm started from the previous one, a few Gauss-Newton steps, each one QP in the
robot's tangent space:

* costs: mapped links follow their human segments' orientations (times the rest-pose offset
  ``R_link = R_segment @ R_offset``), scaled positions of pelvis, hands and feet, smoothness
  toward the previous frame and a faint pull toward the rest pose for redundant joints;
* hard constraints: joint position limits and joint velocity limits at the source frame rate
  (one box on ``dq``), planted feet fixed in position and orientation, sole corners above the
  floor, capsule pairs apart (linearised distance rows).

A foot is planted while the source's foot is in contact and the robot's sole has come down
(lowest corner within ``plant_height`` of the floor, or ``plant_wait`` s after the source's
touch-down; :class:`~ikfusion.retarget.settings.RetargetSettings`); until then, a foot whose
source is in contact is pulled flat onto the floor under the source foot's heading. Frames the
constraints cannot all satisfy are solved with penalised slack and counted, never dropped.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from ..ik.configuration import Configuration
from ..ik.equality_qp import ClosedFormHint
from ..ik.limits.base import Equality, Inequality
from ..ik.qp import QpBuffer, QpSettings, solve_qp, solve_unrelaxed
from ..ik.tasks import DampingTask, OrientationTask, PositionTask
from ..model import layout
from ..model.human_model import HumanModel
from ..rotations import axis_rotation, euler_to_matrix, log_so3
from .capsules import CapsulePairs
from .compiled_step import CompiledConfiguration, robot_step
from .human import hip_height
from .robot_config import RetargetConfig
from .robot_model import RobotModel
from .source import HumanMotion

#: Sides: robot foot key -> source segment prefix.
SIDES = {"left": "Left", "right": "Right"}


class _Anchor(NamedTuple):
    """Where a planted foot's link is held: ``R_world_link`` and ``p_world_link`` [m]."""

    rotation: np.ndarray
    translation: np.ndarray


def _frame_pose(conf: Configuration, frame_id: int) -> tuple[np.ndarray, np.ndarray]:
    """``R_world_frame`` and ``p_world_frame`` [m] of one frame (arrays, no ``pin.SE3``)."""
    if isinstance(conf, CompiledConfiguration):
        return conf.frame_arrays(frame_id)
    T = conf.placement(frame_id)
    return T.rotation, T.translation


@dataclass
class RobotTrajectory:
    """A retargeted motion on a robot.

    Attributes:
        robot: The robot.
        time: (N,) [s].
        q: (N, nq) configurations.
        planted: (N, 2) left/right foot planted.
        relaxed: (N,) frames solved with slack.
        link_targets: ``segment->link`` -> (N, 3, 3) orientation targets of the link.
        position_targets: ``segment->link`` -> (N, 3) position targets of the link [m].
        scale: The human-to-robot length scale used.
        warnings: What the solve could not do as usual (e.g. compile its step function).
    """

    robot: RobotModel
    time: np.ndarray
    q: np.ndarray
    planted: np.ndarray
    relaxed: np.ndarray
    link_targets: dict[str, np.ndarray]
    position_targets: dict[str, np.ndarray]
    scale: float
    warnings: list[str] = field(default_factory=list)

    @property
    def rate(self) -> float:
        """Frame rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.time))) if len(self.time) > 1 else 0.0


@dataclass
class _Targets:
    """Per frame targets of one source motion on one robot."""

    orientations: dict[str, np.ndarray]   # segment -> (N, 3, 3) of its link
    positions: dict[str, np.ndarray]      # segment -> (N, 3) [m] of its link (feet: sole link)
    in_contact: np.ndarray                # (N, 2) the source's feet, left first
    scale: float

    def stacked(self, segments: list[str], tracked: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """Every frame's targets at once, in the tasks' orders.

        Returns:
            Orientation targets (N, k, 3, 3) of ``segments`` (NaN where a segment has none)
            and position targets (N, m, 3) [m] of ``tracked``.
        """
        N = len(self.in_contact)
        R = np.full((N, len(segments), 3, 3), np.nan)
        for i, segment in enumerate(segments):
            if segment in self.orientations:
                R[:, i] = self.orientations[segment]
        p = np.zeros((N, len(tracked), 3))
        for i, segment in enumerate(tracked):
            p[:, i] = self.positions[segment]
        return R, p


@lru_cache(maxsize=1)
def _default_rest() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], float]:
    """The default body's N-pose and hip height [m].

    Segment rotations, and positions relative to the point of the floor under the pelvis.
    """
    model = HumanModel.default()
    q = model.neutral()
    base = model.segment_position(q, "Pelvis") * [1.0, 1.0, 0.0]
    R = {s: model.segment_rotation(q, s) for s in model.segment_names}
    p = {s: model.segment_position(q, s) - base for s in model.segment_names}
    return R, p, hip_height(model)


def _human_rest(source: HumanMotion) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The source body's N-pose: segment rotations and positions relative to the pelvis [m].

    The default body scaled so that its hips stand as high as the source's.
    """
    R, p, hips = _default_rest()
    scale = source.hip_height / hips
    return R, {s: scale * v for s, v in p.items()}


def _robot_rest(robot: RobotModel) -> tuple[dict[str, pin.SE3], np.ndarray]:
    """Link placements in the rest pose with the root above the origin, and the root xy."""
    links = set(robot.config.links.values()) | {f.link for f in robot.config.feet.values()}
    return {link: robot.placement(robot.rest, link) for link in links}, robot.rest[:2].copy()


def build_targets(source: HumanMotion, robot: RobotModel) -> _Targets:
    """Orientation and scaled position targets of the robot's links, and the source's contacts.

    A link's position target is ``scale * p_segment + R_segment @ o``, with the offset ``o``
    fixed in the segment frame so that both rest poses coincide; its orientation target is
    ``R_segment @ R_offset`` with ``R_offset`` from the two rest poses (or the config).
    """
    config = robot.config
    scale = config.scale or robot.hip_height() / source.hip_height
    R_rest, p_rest = _human_rest(source)
    links_rest, root_xy = _robot_rest(robot)
    index = {s: i for i, s in enumerate(source.segments)}
    orientations, positions = {}, {}
    for segment, link in config.links.items():
        if segment not in index:
            continue
        R_seg = source.R_world_segment[:, index[segment]]
        if segment in config.orientation_offsets_deg:
            roll, pitch, yaw = np.radians(config.orientation_offsets_deg[segment])
            R_offset = euler_to_matrix("ZYX", [yaw, pitch, roll])
        else:
            R_offset = R_rest[segment].T @ links_rest[link].rotation
        orientations[segment] = R_seg @ R_offset
    for segment, weight in config.position_weights.items():
        tracked = _position_link(config, segment)
        if segment not in index or tracked is None or weight <= 0:
            continue
        robot_rest = links_rest[tracked].translation - [*root_xy, 0.0]
        offset = R_rest[segment].T @ (robot_rest - scale * p_rest[segment])
        positions[segment] = (scale * source.p_world_segment[:, index[segment]]
                           + source.R_world_segment[:, index[segment]] @ offset)
    in_contact = np.zeros((len(source), 2), dtype=bool)
    for i, prefix in enumerate(SIDES.values()):
        cols = [k for k, n in enumerate(source.contact_names)
                if n.startswith(prefix) and n in layout.CONTACT_SITES]  # feet, not knees, palms
        if cols:
            in_contact[:, i] = source.contacts[:, cols].any(axis=1)
    return _Targets(orientations, positions, in_contact, float(scale))


def _position_link(config: RetargetConfig, segment: str) -> str | None:
    """The robot link whose origin tracks ``segment``'s scaled position (feet: the sole's link)."""
    for side, prefix in SIDES.items():
        if segment == f"{prefix}Foot":
            return config.feet[side].link
    return config.links.get(segment)


def _selection(mask: np.ndarray) -> slice | np.ndarray:
    """``mask`` as a slice when its true entries are consecutive (indexing makes a view)."""
    where = np.flatnonzero(mask)
    if not len(where):
        return slice(0, 0)
    if where[-1] - where[0] + 1 == len(where):
        return slice(int(where[0]), int(where[-1]) + 1)
    return mask


def _heading(R: np.ndarray) -> float:
    """Yaw of a world rotation [rad] (its x axis's direction on the floor)."""
    return float(np.arctan2(R[1, 0], R[0, 0]))


class RobotRetargeter:
    """Solves a source motion onto one robot (see the module docstring).

    Args:
        robot: The robot model with its config (whose ``solver`` holds the settings).
        qp: The QP backends' iteration limits and slack weights (``configs/solver.yaml``).
    """

    def __init__(self, robot: RobotModel, qp: QpSettings) -> None:
        self.robot = robot
        config = robot.config
        s = self.settings = config.solver
        self.backend = s.backend
        self._qp = qp
        model = robot.model
        self.segments = list(config.links)
        self.orientation_task = OrientationTask(
            [robot.frame_ids[config.links[n]] for n in self.segments], self.segments,
            s.orientation_weight)
        self.feet = [config.feet[side] for side in SIDES]
        self._foot_ids = [robot.frame_ids[f.link] for f in self.feet]
        self.flat_task = OrientationTask(self._foot_ids, [f.link for f in self.feet],
                                         s.flat_foot_weight)
        self.capsules = CapsulePairs(config.capsules, config.collision_pairs, robot.frame_ids)
        n = model.nv - 6
        self.smoothness = DampingTask(np.full(model.nv, s.smoothness))
        self.rest_pull = DampingTask(np.concatenate([np.zeros(6), np.full(n, s.rest_pull)]))
        self.rest_pull.set_reference(robot.rest)
        self._max_velocity = np.concatenate([np.full(3, s.max_root_velocity),
                                             np.full(3, s.max_root_angular_velocity),
                                             robot.max_velocity])
        rest_feet = [robot.placement(robot.rest, f.link) for f in self.feet]
        self._rest_feet = [T.rotation for T in rest_feet]
        self._rest_feet_z = [float(T.translation[2]) for T in rest_feet]
        self._configuration = Configuration(model, robot.rest)
        self._cost_data = model.createData()  # for :meth:`_cost`
        self._qp_buffer = QpBuffer(model.nv)
        # DAQP at once after a step where a limit bound (the closed-form try would fail)
        self._closed_form = ClosedFormHint()
        self._no_plants = Equality(np.zeros((0, model.nv)), np.zeros(0))
        self._ones = np.ones(len(self.segments)), np.ones(len(self.feet))
        self._stacked = np.zeros((0, len(self.segments), 3, 3)), np.zeros((0, 0, 3))
        self._none = np.zeros(0, dtype=int)
        self._no_flat = np.full((len(self.feet), 3, 3), np.nan)
        self._flat_off = False  # whether the flat-foot task is set to no foot
        # Sole corners (4 per foot) of the feet in the air, by which feet are planted.
        self._air = {planted: _selection(np.repeat(np.logical_not(planted), 4))
                     for planted in itertools.product((False, True), repeat=len(self.feet))}

    def solve(self, source: HumanMotion, progress: bool = False) -> RobotTrajectory:
        """Retarget every frame of ``source``."""
        config = self.robot.config
        targets = build_targets(source, self.robot)
        tracked = list(targets.positions)
        self.position_task = PositionTask(
            [self.robot.frame_ids[_position_link(config, s) or ""] for s in tracked], tracked)
        self._position_weights = np.array([config.position_weights[s] for s in tracked])
        self._configuration, warnings = self._step_configuration()
        N = len(source)
        dt = 1.0 / source.rate if source.rate > 0 else 0.0
        q_all = np.zeros((N, self.robot.model.nq))
        planted = np.zeros((N, 2), dtype=bool)
        relaxed = np.zeros(N, dtype=bool)
        anchors: list[_Anchor | None] = [None, None]
        waited = np.zeros(2)
        self._stacked = targets.stacked(self.segments, tracked)
        self._flat_off = False
        self._closed_form.skip = False
        q = self._initial(targets)
        for k in tqdm(range(N), disable=not progress, desc="retarget", unit="frame"):
            self._set_targets(targets, k, anchors)
            first = k == 0
            if first:
                q = self._first_pose(q, dt, anchors)
            if k >= 2:  # warm start: the previous frame moved on at the same velocity
                q = self._extrapolate(q_all[k - 2], q_all[k - 1])
            steps = self.settings.first_frame_steps if first else self.settings.max_steps
            q, relaxed[k] = self._solve_frame(q, None if first else q_all[k - 1], dt, anchors,
                                              steps)
            q_all[k] = q
            self._update_plants(targets.in_contact[k], q, anchors, waited, dt)
            planted[k] = [a is not None for a in anchors]
        return RobotTrajectory(
            self.robot, source.time.copy(), q_all, planted, relaxed,
            {f"{s}->{config.links[s]}": R for s, R in targets.orientations.items()},
            {f"{s}->{_position_link(config, s)}": p for s, p in targets.positions.items()},
            targets.scale, warnings)

    def _step_configuration(self) -> tuple[Configuration, list[str]]:
        """The configuration the steps use, with its compiled kinematics and objective.

        Plain Pinocchio kinematics and NumPy tasks for joint types the compiled step does
        not cover. Returns it and the warnings of building it (a failed native compile).
        """
        model = self.robot.model
        frames = [*self._foot_ids, *self.position_task.frame_ids]
        self._foot_rows: list[int] = []
        try:
            step = robot_step(model, [*self.orientation_task.frame_ids,
                                      *self.flat_task.frame_ids],
                              self.position_task.frame_ids, list(dict.fromkeys(frames)),
                              self.capsules, self._foot_ids)
        except NotImplementedError:
            return Configuration(model, self.robot.rest), []
        conf = CompiledConfiguration(model, self.robot.rest, step,
                                     [self.orientation_task, self.flat_task],
                                     self.position_task, self.capsules,
                                     np.array([f.corners for f in self.feet]))
        self._foot_rows = [conf.frame_row(fid) for fid in self._foot_ids]
        return conf, list(step.warnings)

    def _tracking_objective(self, conf: Configuration) -> tuple[np.ndarray, np.ndarray]:
        """``H`` and ``c`` of the orientation, flat-foot and position tasks at ``conf``."""
        if isinstance(conf, CompiledConfiguration):
            return conf.tracking_objective()
        nv = conf.model.nv
        H, c = np.zeros((nv, nv)), np.zeros(nv)
        for task in (self.orientation_task, self.flat_task, self.position_task):
            task.add_objective(conf, H, c)
        return H, c

    def _first_pose(self, q_rest: np.ndarray, dt: float,
                    anchors: list[_Anchor | None]) -> np.ndarray:
        """The start of the first frame's solve: the best of several screened starts.

        The starts: the rest pose, and ``first_frame_starts`` - 1 poses with random arms
        within their ranges (seeded). Rounds of ``first_frame_screen_steps`` steps each keep
        the better half (the lowest tracking cost) until two are left, whose better one the
        caller solves on: the start that ends in the lowest basin leads within a few steps,
        while the others, mostly stuck, need no more.

        Orientation targets alone have local minima far from the answer (an arm raised with
        its elbow bent 140 deg is met from the hanging rest pose with the elbow straight);
        later frames start from the previous one and stay in the basin found here.
        """
        rng = np.random.default_rng(0)
        arms = self._arm_dofs()
        pool = []
        for start in range(self.settings.first_frame_starts):
            q = q_rest.copy()
            if start:
                q[7 + arms] = rng.uniform(self.robot.lower[arms], self.robot.upper[arms])
            pool.append(q)
        steps = min(self.settings.first_frame_screen_steps, self.settings.first_frame_steps)
        while True:
            solved = [self._solve_frame(q, None, dt, anchors, steps)[0] for q in pool]
            costs = [self._cost(q) for q in solved]
            order = sorted(range(len(solved)), key=costs.__getitem__)
            if len(order) <= 2:
                return solved[order[0]]
            pool = [solved[i] for i in order[:(len(order) + 1) // 2]]

    def _arm_dofs(self) -> np.ndarray:
        """Indices into ``q[7:]`` of the joints between the trunk link and the hand links."""
        model, links = self.robot.model, self.robot.config.links
        def chain(link: str) -> set[int]:
            joint = model.frames[self.robot.frame_ids[link]].parentJoint
            out = set()
            while joint > 1:
                out.add(joint)
                joint = model.parents[joint]
            return out
        trunk = chain(links["T8"]) if "T8" in links else set()
        hands = set().union(*(chain(links[h]) for h in ("LeftHand", "RightHand") if h in links))
        return np.array(sorted(model.joints[j].idx_q - 7 for j in hands - trunk), dtype=int)

    def _cost(self, q: np.ndarray) -> float:
        """The tracking objective at ``q`` (orientations and positions).

        From Pinocchio's frame placements alone (no Jacobian, no compiled step: only the
        screening of first-frame starts compares these values).
        """
        model, data = self.robot.model, self._cost_data
        pin.framesForwardKinematics(model, data, q)
        total = 0.0
        for task in (self.orientation_task, self.flat_task):
            weights = task.row_weights()
            if weights.any():
                R = np.array([data.oMf[f].rotation for f in task.frame_ids])
                e = log_so3(R @ np.swapaxes(task.targets, 1, 2)).reshape(-1)
                total += float(np.sum(weights * e * e))
        position = self.position_task
        weights = position.row_weights()
        if weights.any():
            p = np.array([data.oMf[f].translation for f in position.frame_ids])
            e = (p - position.targets).reshape(-1)
            total += float(np.sum(weights * e * e))
        return total

    def _extrapolate(self, q_before: np.ndarray, q_last: np.ndarray) -> np.ndarray:
        """``q_last`` moved on by the last frame's motion, joints kept in their limits."""
        model = self.robot.model
        q = pin.integrate(model, q_last, pin.difference(model, q_before, q_last))
        q[7:] = np.minimum(np.maximum(q[7:], self.robot.lower), self.robot.upper)  # np.clip
        return q

    def _initial(self, targets: _Targets) -> np.ndarray:
        """The rest pose, moved under the first frame's pelvis target."""
        q = self.robot.rest.copy()
        if "Pelvis" in targets.positions:
            q[:2] = targets.positions["Pelvis"][0, :2]
        return q

    def _set_targets(self, targets: _Targets, k: int, anchors: list[_Anchor | None]) -> None:
        """This frame's targets; a foot coming down is pulled flat onto the floor."""
        R_all, p_all = self._stacked
        self.orientation_task.set_targets(R_all[k], self._ones[0])
        tracked = self.position_task.names
        p = p_all[k].copy()
        flat = None
        for i, prefix in enumerate(SIDES.values()):
            segment = f"{prefix}Foot"
            if not targets.in_contact[k, i] or anchors[i] is not None:
                continue
            if flat is None:
                flat = self._no_flat.copy()
            if segment in targets.orientations:
                yaw = _heading(targets.orientations[segment][k] @ self._rest_feet[i].T)
                flat[i] = axis_rotation("z", yaw) @ self._rest_feet[i]
            if segment in tracked:  # onto the floor: its rest height
                p[tracked.index(segment), 2] = self._rest_feet_z[i]
        if flat is not None or not self._flat_off:  # no foot stays no foot: nothing to set
            self.flat_task.set_targets(self._no_flat if flat is None else flat, self._ones[1])
            self._flat_off = flat is None
        self.position_task.set_targets(p, self._position_weights)

    def _solve_frame(self, q: np.ndarray, q_previous: np.ndarray | None, dt: float,
                     anchors: list[_Anchor | None], steps: int) -> tuple[np.ndarray, bool]:
        """Gauss-Newton steps from ``q``; returns the configuration and whether it relaxed.

        It stops after a small step that leaves planted feet held, capsules apart and soles
        above the floor (up to the linearisation's round-off).
        """
        s = self.settings
        conf = self._configuration
        conf.update(q)
        self.smoothness.set_reference(q_previous)
        relaxed = False
        previous: np.ndarray | None = None
        factor = 1.0
        for step in range(steps):
            H, c = self._tracking_objective(conf)
            # Since the previous frame (the smoothness task's error too) [rad, m].
            moved = None if q_previous is None else conf.difference(q_previous)
            self.smoothness.add_objective(conf, H, c, error=moved)
            self.rest_pull.add_objective(conf, H, c)
            near = self.capsules.inequality(conf)
            rows = ([self._floor_rows(conf, anchors), near], [self._plant_rows(conf, anchors)])
            moving = (near.G[:, 6:] != 0.0).any(axis=0).nonzero()[0] + 6 \
                if step < s.trusted_steps and len(near.h) else self._none
            box = self._box(q, moved, dt, moving)
            assemble = self._qp_buffer.assemble
            problem = assemble(H, c, *rows, box, s.levenberg_marquardt)
            # within the trust region, the constraints held or nothing (its relaxation would
            # be thrown away): when they cannot all hold, the region was too tight
            trusted = solve_unrelaxed(problem, self.backend, self._qp, self._closed_form) \
                if len(moving) else None
            if trusted is not None:
                solution = trusted
            else:
                if len(moving):
                    box = self._box(q, moved, dt)
                    problem = assemble(H, c, *rows, box, s.levenberg_marquardt)
                solution = solve_qp(problem, self.backend, self._qp, self._closed_form)
            relaxed |= solution.relaxed
            factor = self._damped(solution.dq, previous, factor)
            # The box holds to the QP's tolerance; clipped, limits hold exactly.
            dq = previous = factor * np.minimum(np.maximum(solution.dq, box[0]), box[1])
            q = conf.integrate(dq)
            conf.update(q)
            far = self.capsules.last_min_distance > s.capsules_far  # at the pose stepped from
            if np.abs(dq).max() < s.step_tolerance and self._settled(conf, anchors, not far):
                break
        return q, relaxed

    def _damped(self, dq: np.ndarray, previous: np.ndarray | None, factor: float) -> float:
        """The step scale for ``dq``: halved each time a step turns back on the previous one.

        Linearised capsule distances overestimate the true ones (a distance is a minimum over
        the capsules' points), so full steps can overshoot back and forth between two poses;
        shrinking the steps once that starts makes them settle between the two.
        """
        if previous is not None and float(dq @ previous) < -0.5 * math.sqrt(
                float(dq @ dq)) * math.sqrt(float(previous @ previous)):
            return 0.5 * factor
        return factor

    def _settled(self, conf: Configuration, anchors: list[_Anchor | None],
                 capsules: bool = True) -> bool:
        """Planted feet held, soles above the floor and capsule pairs apart at ``conf``.

        ``capsules=False`` skips the pairs: after a small step from a pose where every pair
        was ``capsules_far`` apart none can touch.
        """
        return self._violation(conf, anchors, 0.0, capsules) <= self.settings.hold_tolerance

    def _violation(self, conf: Configuration, anchors: list[_Anchor | None],
                   margin: float | None = None, capsules: bool = True) -> float:
        """How far ``conf`` breaks the constraints [m] (0 when it keeps them all).

        Planted feet off their anchors, soles below the floor, capsule pairs closer than
        ``margin`` (the rows' margin when None).
        """
        if isinstance(conf, CompiledConfiguration):  # no Jacobians needed
            p, witnesses, z = conf.constraint_values()
            feet = [p[row] for row in self._foot_rows]
            floor = z[self._air_corners(anchors)]
            # the closest witness: the smallest of the pairs' distances
            gaps = witnesses if capsules else self._none
        else:
            feet = [conf.placement(fid).translation for fid in self._foot_ids]
            floor = self._floor_rows(conf, anchors).h
            gaps = self.capsules.distances(conf) if capsules else np.zeros(0)
        worst = 0.0
        for foot, anchor in zip(feet, anchors):
            if anchor is not None:
                gap = foot - anchor.translation
                worst = max(worst, math.sqrt(float(gap @ gap)))
        if len(floor):
            worst = max(worst, -float(floor.min()))
        if len(gaps):
            keep = self.capsules.margin if margin is None else margin
            worst = max(worst, keep - float(gaps.min()))
        return worst

    def _box(self, q: np.ndarray, moved: np.ndarray | None, dt: float,
             trusted: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits and velocity limits as bounds on ``dq``.

        ``moved`` is ``q ⊖ q_previous`` (None on a frame without a previous one).

        The ``trusted`` tangent coordinates (joints that move a capsule near another) also
        move at most ``trust_step`` in this step, so that the linearised distances stay
        close to the true ones.
        """
        nv = self.robot.model.nv
        lb, ub = np.empty(nv), np.empty(nv)
        lb[:6], ub[:6] = -np.inf, np.inf
        np.subtract(self.robot.lower, q[7:], out=lb[6:])
        np.subtract(self.robot.upper, q[7:], out=ub[6:])
        if trusted is not None and len(trusted):
            step = self.settings.trust_step
            lb[trusted] = np.maximum(lb[trusted], -step)
            ub[trusted] = np.minimum(ub[trusted], step)
        if moved is not None and dt > 0:
            span = self._max_velocity * dt
            np.maximum(lb, -span - moved, out=lb)
            np.minimum(ub, span - moved, out=ub)
        np.minimum(lb, 0.0, out=lb)
        np.maximum(ub, 0.0, out=ub)
        return lb, ub

    def _floor_rows(self, conf: Configuration, anchors: list[_Anchor | None]) -> Inequality:
        """Sole corners of feet in the air stay above the floor: ``-J_z dq <= z``.

        A planted foot has none: its anchor is on or above the floor, and rows that repeat
        its equality rows would make the QP degenerate.
        """
        if isinstance(conf, CompiledConfiguration):
            z, Jz = conf.sole_corners()
            air = self._air_corners(anchors)
            return Inequality(-Jz[air], z[air])
        G, h = [np.zeros((0, conf.model.nv))], [np.zeros(0)]
        for foot, fid, anchor in zip(self.feet, self._foot_ids, anchors):
            if anchor is not None:
                continue
            T = conf.placement(fid)
            J = conf.jacobian(fid)
            r = foot.corners @ T.rotation.T  # corners from the link origin, world axes
            G.append(-(J[2] + r[:, 1:2] * J[3] - r[:, 0:1] * J[4]))  # z rows of J_lin - [r]x J_ang
            h.append(T.translation[2] + r[:, 2])
        return Inequality(np.vstack(G), np.concatenate(h))

    def _air_corners(self, anchors: list[_Anchor | None]) -> slice | np.ndarray:
        """The sole corners (4 per foot, feet in order) of the feet not planted.

        A slice when they are consecutive (with two feet always), else a mask.
        """
        return self._air[tuple(anchor is not None for anchor in anchors)]

    def _plant_rows(self, conf: Configuration, anchors: list[_Anchor | None]) -> Equality:
        """Planted feet keep their anchor placement: 6 rows per foot."""
        rows, b = [], []
        for fid, anchor in zip(self._foot_ids, anchors):
            if anchor is None:
                continue
            R, p = _frame_pose(conf, fid)
            rows.append(conf.jacobian(fid))
            b += [anchor.translation - p, log_so3(anchor.rotation @ R.T)]
        if not rows:
            return self._no_plants
        return Equality(rows[0] if len(rows) == 1 else np.vstack(rows), np.concatenate(b))

    def _update_plants(self, in_contact: np.ndarray, q: np.ndarray,
                       anchors: list[_Anchor | None], waited: np.ndarray, dt: float) -> None:
        """Plant feet whose source foot is down and whose sole reached the floor; lift others."""
        s = self.settings
        self._configuration.update(q)
        for i, (foot, fid) in enumerate(zip(self.feet, self._foot_ids)):
            if not in_contact[i]:
                anchors[i] = None
                waited[i] = 0.0
                continue
            if anchors[i] is not None:
                continue
            waited[i] += dt
            T = self._configuration.placement(fid)
            lowest = float(np.min((foot.corners @ T.rotation.T + T.translation)[:, 2]))
            if lowest <= s.plant_height or waited[i] >= s.plant_wait:
                drop = lowest if 0.0 < lowest <= s.plant_height else 0.0  # onto the floor
                anchors[i] = _Anchor(T.rotation.copy(), T.translation - [0.0, 0.0, drop])
