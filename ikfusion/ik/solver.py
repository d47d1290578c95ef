"""The whole-body solver: each frame a few Gauss-Newton steps, each a QP in the tangent space.

Per frame, warm started from the previous frame:

* costs: segment orientations (IMU), site positions (UWB, markers), a posture prior on joints
  the sensors leave open, smoothness toward the previous frame, the bend of sensed joints away
  from their sensors kept from the previous frame (``persistence``), the pelvis across
  hand-overs and swing feet led by a correction (:mod:`.support`), and during flight a
  ballistic pelvis path;
* constraints: anatomical ranges of motion (linearised), contact points in contact held at
  their touch-down anchors (no slip), contact points above the floor, velocity bounds.

Global translation without aiding comes from chaining contacts: the planted foot is the anchor.
A leg that lets go of the floor eases back to its sensors (:mod:`.release`), so what the contact
bent does not snap back in one frame.
"""

from __future__ import annotations

import copy
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from ..errors import SolverError
from ..model.human_model import HumanModel
from ..rotations import axis_rotation, log_so3, matrix_to_quat_wxyz, wxyz_to_xyzw
from .assumed import AssumedTargets
from .compiled import SensedPoseSpec, compiled_kinematics
from .configuration import Configuration
from .contacts import ContactState, ContactThresholds, release_contacts, touch_down
from .frame import Frame
from .limits import ContactConstraint, FloorLimit, Inequality, JointRangeLimit, VelocityLimit
from .limits.joint_range import LinearisedRanges
from .pose import Motion, Pose
from .qp import QpProblem, QpSolution, assemble_qp, build_qp, solve_qp
from .release import ReleaseEasing
from .settings import SolverSettings
from .support import SupportFollower
from .tasks import DampingTask, OrientationTask, PositionTask, PostureTask, Task

GRAVITY = np.array([0.0, 0.0, -9.81])



@dataclass
class _LazyRows:
    """What a step's QP left out, to add if the step needs it."""

    ranges: LinearisedRanges
    up: np.ndarray      # upper limits in the QP
    down: np.ndarray    # lower limits in the QP
    floor: Inequality   # the floor rows (always in the QP, kept to rebuild it)
    bounds: tuple[np.ndarray, np.ndarray] | None


class Solver:
    """Frame-by-frame whole-body IK on a :class:`HumanModel`.

    Args:
        model: The human model.
        settings: Weights, limits and thresholds; ``configs/solver.yaml`` when omitted.
        **overrides: Individual settings (e.g. ``backend="proxqp"``).
    """

    def __init__(self, model: HumanModel, settings: SolverSettings | None = None,
                 **overrides: Any) -> None:
        base = settings if settings is not None else SolverSettings.load()
        self.settings = replace(base, **overrides) if overrides else base
        self.model = model
        s = self.settings
        segments = model.segment_names
        self._segment_index = {n: i for i, n in enumerate(segments)}
        self.orientation_task = OrientationTask(
            [model.segment_frame_id(n) for n in segments], segments, s.orientation)
        sites = model.site_names
        self._site_index = {n: i for i, n in enumerate(sites)}
        self.position_task = PositionTask([model.site_frame_id(n) for n in sites], sites,
                                          s.position)
        self.posture_task = PostureTask.from_joints(model.ball_joints, s.posture_joints, s.posture,
                                                    s.posture_axes)
        self._posture_weights = self.posture_task.weights.copy()
        self.assumed = AssumedTargets(segments, model.ball_joints, s.hinge_joints)
        self._joint_segments = [(j.spec.parent, j.spec.child) for j in model.ball_joints.values()]
        self._joint_parent = np.array([self._segment_index[a] for a, _ in self._joint_segments],
                                      dtype=int)
        self._joint_child = np.array([self._segment_index[b] for _, b in self._joint_segments],
                                     dtype=int)
        self._toe_joints = [(k, self._segment_index[j.spec.parent])
                            for k, j in enumerate(model.ball_joints.values())
                            if j.name.endswith("BallFoot") and j.spec.angles[0].name == "flex"]
        self._toe_flexion = {}
        for k, _ in self._toe_joints:
            flex = list(model.ball_joints.values())[k].spec.angles[0]
            axis = np.eye(3)["xyz".index(flex.axis)] * flex.sign
            self._toe_flexion[k] = (axis, np.radians(flex.lower_deg), np.radians(flex.upper_deg))
        self._joint_q_cols = np.array([j.idx_q for j in model.ball_joints.values()],
                                      dtype=int)[:, None] + np.arange(4)
        self.damping_task = DampingTask(self._tangent_vector(
            s.smoothness_root_translation, s.smoothness_root_rotation, s.smoothness_joints))
        self.persistence_task = DampingTask(np.zeros(model.model.nv))
        self._joint_v_cols = np.array([j.idx_v for j in model.ball_joints.values()],
                                      dtype=int)[:, None] + np.arange(3)
        root_frame = model.segment_frame_id(segments[0])
        self.root_task = PositionTask([root_frame], [segments[0]])
        self.contact_names = model.sites_of_kind("contact") if s.contacts else []
        contact_ids = [model.site_frame_id(n) for n in self.contact_names]
        self.support = SupportFollower(self.contact_names, s.lag_speed, s.lag_max, s.swing_speed,
                                       s.lean_max, s.lean_speed, s.touchdown_confirm)
        self.swing_task = PositionTask(contact_ids, self.contact_names, s.swing)
        self.contact_constraint = ContactConstraint(contact_ids, self.contact_names)
        self._heels = np.array(["Heel" in n for n in self.contact_names], dtype=bool)
        self.floor_limit = FloorLimit(contact_ids, s.floor_z)
        self.joint_limits = JointRangeLimit(model.ball_joints, s.joint_range_margin_deg)
        self.velocity_limit = VelocityLimit(self._tangent_vector(
            s.max_root_velocity, s.max_root_angular_velocity, s.max_joint_velocity))
        self.thresholds = ContactThresholds.from_settings(s)
        self._site_frames = [model.site_frame_id(n) for n in sites] + [root_frame]
        self._contact_rows = np.array([self._site_index[n] for n in self.contact_names], dtype=int)
        self._contact_ids = contact_ids
        self._kinematics = None
        if s.compiled:
            try:
                self._kinematics = compiled_kinematics(
                    model.model, self.orientation_task.frame_ids,
                    list(model.ball_joints.values()), self._site_frames, self._sensed_spec())
                self._geometry = self._kinematics.geometry(model.model)
            except NotImplementedError:
                self._kinematics = None
        self._configuration = Configuration(model.model, model.neutral())
        self._sensed_data = model.model.createData()
        self._identities = np.tile(np.eye(3), (len(segments), 1, 1))
        self._positions_set = True  # the position task starts without targets: clear it once
        self._contact_feet = np.array([self._segment_index.get(
            f"{'Left' if n.startswith('Left') else 'Right'}Foot", -1) for n in self.contact_names],
            dtype=int)
        self.easing = ReleaseEasing([self._leg_of(foot) for foot in self._contact_feet],
                                    len(segments), np.radians(s.ease_speed_deg))
        self.reset()

    def _leg_of(self, foot: int) -> np.ndarray:
        """Segment indices from ``foot`` up to the pelvis, the pelvis excluded (none: -1)."""
        parent = dict(zip(self._joint_child.tolist(), self._joint_parent.tolist()))
        leg = []
        while foot > 0:
            leg.append(foot)
            foot = parent.get(foot, 0)
        return np.array(leg, dtype=int)

    def _sensed_spec(self) -> SensedPoseSpec:
        """What :meth:`_sensed_configuration` does, for the compiled sensed-pose function."""
        model = self.model.model
        root_joint = model.frames[self.orientation_task.frame_ids[0]].parentJoint
        joints = list(self.model.ball_joints.values())
        toes = []
        for k, foot in self._toe_joints:
            axis, lower, upper = self._toe_flexion[k]
            x, y, z = (float(a) for a in axis)
            toes.append((joints[k].joint_id, foot, int(self._joint_child[k]), (x, y, z),
                         float(lower), float(upper)))
        return SensedPoseSpec(
            root=(root_joint, 0),
            joints=tuple((j.joint_id, int(p), int(c)) for j, p, c in
                         zip(joints, self._joint_parent, self._joint_child)),
            toes=tuple(toes), points=tuple(self._contact_ids))

    def _sensed_pose(self, q: np.ndarray, tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensed configuration at ``q`` and its contact points (c, 3) [m].

        The configuration keeps the toes of ``q`` (the posture prior decides them); the points
        are those with level toes (see :meth:`_sensed_configuration`).
        """
        kin = self._kinematics
        if kin is not None and kin.sensed_function is not None:
            return kin.sensed_pose(q, self.orientation_task.targets, self._geometry,
                                   tracked.astype(float))
        return (self._sensed_configuration(q, tracked, level_toes=False),
                self._contact_positions(self._sensed_configuration(q, tracked)))

    def _tangent_vector(self, root_linear: float, root_angular: float,
                        joints: float) -> np.ndarray:
        v = np.full(self.model.model.nv, joints, dtype=float)
        v[:3], v[3:6] = root_linear, root_angular
        return v

    # ------------------------------------------------------------------ state
    def reset(self, q: np.ndarray | None = None) -> None:
        """Forget the previous frames (the next frame is solved from scratch, or from ``q``)."""
        self._q: np.ndarray | None = None if q is None else np.asarray(q, dtype=float).copy()
        self._q_start = self._q
        self._time: float | None = None
        self._contacts = ContactState.empty(self.contact_names)
        self._failures: list[str] = []
        self._history: deque[tuple[float, np.ndarray]] = deque(
            maxlen=max(2, self.settings.speed_window + 1))
        self._p_sensed = np.zeros((len(self.contact_names), 3))
        self._pitch = np.zeros(len(self.contact_names))
        self._root_velocity = np.zeros(3)
        self.support.reset()
        self.easing.reset()
        self._bent: np.ndarray | None = None  # solved pose minus sensed pose (tangent, nv)
        self._heading = 0.0
        self._R_heading: np.ndarray | None = None

    # ------------------------------------------------------------------ position corrections
    def shift_anchors(self, delta: np.ndarray) -> None:
        """Move every planted point by ``delta`` (3,) [m], horizontal part only.

        The body follows its feet, which slide: the ``slide`` correction of a drifting position.
        """
        d = np.array([float(delta[0]), float(delta[1]), 0.0])
        self.support.shift(d)
        anchors = self._contacts.anchors.copy()
        anchors[self._contacts.active] += d
        self._contacts = replace(self._contacts, anchors=anchors)

    def translate(self, delta: np.ndarray) -> None:
        """Move the whole solved state by ``delta`` (3,) [m], horizontal part only.

        Body, anchors and contact history move together, e.g. to place the body where the first
        absolute fix says.
        """
        d = np.array([float(delta[0]), float(delta[1]), 0.0])
        self.support.shift(d)
        if self._q is not None:
            self._q = self._q.copy()
            self._q[:3] += d
        self._contacts = replace(self._contacts, anchors=self._contacts.anchors + d)
        self._history = deque(((t, p + d) for t, p in self._history),
                              maxlen=self._history.maxlen)

    def turn(self, yaw: float) -> None:
        """Turn every orientation target by ``yaw`` [rad] more about the vertical, from now on.

        The heading correction of sensors whose heading drifted (a magnetically disturbed
        hall): the body turns with its targets, the position correction takes it from there.
        """
        self._heading += float(yaw)
        self._R_heading = axis_rotation("z", self._heading)

    @property
    def shifted(self) -> np.ndarray:
        """How far the position corrections have moved the body so far (3,) [m]."""
        return self.support.displacement

    @property
    def heading_correction(self) -> float:
        """The accumulated turn of the orientation targets [rad]."""
        return self._heading

    def set_step_offset(self, offset: np.ndarray, max_step: float) -> None:
        """Lead feet that lift off from now on toward the correction ``offset`` (3,) [m].

        Horizontal part only; each step takes at most ``max_step`` [m] of it.

        Planted points never move: each swing foot is led gradually to its offset and the
        pelvis follows it after touch-down (:class:`SupportFollower`), so the body moves toward
        the corrected position one step at a time: the ``no-slide`` correction.
        """
        self.support.set_step(offset, max_step)

    @property
    def contacts(self) -> ContactState:
        """The current contact state (for the next frame)."""
        return self._contacts

    # ------------------------------------------------------------------ targets
    def _set_targets(self, frame: Frame) -> np.ndarray:
        """Load a frame's targets into the tasks; returns the tracked-segment mask."""
        n = len(self._segment_index)
        R = self._identities.copy()
        w = np.zeros(n)
        for name, R_target in frame.orientations.items():
            i = self._segment_index.get(name)
            if i is None:
                self.model.segment_frame_id(name)  # raises NameNotFound with the valid names
                continue
            R[i] = R_target if self._R_heading is None else self._R_heading @ R_target
            w[i] = frame.orientation_weights.get(name, 1.0)
        if self.settings.assumed > 0:  # open hinge parents (a thigh between pelvis and shank)
            for i, R_assumed in self.assumed.targets(R, w > 0):
                R[i], w[i] = R_assumed, self.settings.assumed
        self.orientation_task.set_targets(R, w)
        self._sensed_targets = self.orientation_task.targets
        tracked = self.orientation_task.weights > 0
        if frame.positions or self._positions_set:
            self._set_position_targets(frame)
        self._positions_set = bool(frame.positions)
        both = tracked[self._joint_parent] & tracked[self._joint_child]
        self._sensed_joints = self._joint_v_cols[both].ravel()  # their tangent columns
        self.posture_task.weights = np.where(both, 0.0, self._posture_weights)
        self._row_weights = (self.orientation_task.row_weights(), self.posture_task.row_weights())
        return tracked

    def _set_position_targets(self, frame: Frame) -> None:
        """Load a frame's site position targets (sites without one get zero information)."""
        m = len(self._site_index)
        p = np.zeros((m, 3))
        info = np.zeros((m, 3, 3))
        for name, p_target in frame.positions.items():
            if name not in self._site_index:
                self.model.site_frame_id(name)
            i = self._site_index[name]
            p[i] = p_target
            weight = np.asarray(frame.position_weights.get(name, 1.0), dtype=float)
            info[i] = weight * np.eye(3) if weight.ndim == 0 else weight
        self.position_task.set_targets(p, info)

    def _sensed_configuration(self, q: np.ndarray, tracked: np.ndarray,
                              level_toes: bool = True) -> np.ndarray:
        """``q`` with the root and every joint between two tracked segments set from targets.

        This is the pose the sensors say, before the constraints bend anything; with
        ``level_toes``, unsensed toes under a sensed foot lie flat on heel-off.
        """
        qs = q.copy()
        T = self.orientation_task.targets
        both = tracked[self._joint_parent] & tracked[self._joint_child]
        if tracked[0]:
            qs[3:7] = wxyz_to_xyzw(matrix_to_quat_wxyz(T[0]))
        if both.any():
            R = np.swapaxes(T[self._joint_parent[both]], 1, 2) @ T[self._joint_child[both]]
            qs[self._joint_q_cols[both]] = wxyz_to_xyzw(matrix_to_quat_wxyz(R))
        for joint, foot in self._toe_joints if level_toes else ():
            if tracked[foot] and not tracked[self._joint_child[joint]]:
                qs[self._joint_q_cols[joint]] = self._level_toe(T[foot], joint)
        # q and -q are one rotation: keep the hemisphere of q, so that q stays continuous
        blocks = np.vstack([np.arange(3, 7)[None], self._joint_q_cols])
        flip = np.einsum("ij,ij->i", qs[blocks], q[blocks]) < 0.0
        qs[blocks[flip]] *= -1.0
        return qs

    def _level_toe(self, R_world_foot: np.ndarray, joint: int) -> np.ndarray:
        """Toe joint quaternion (x, y, z, w) keeping an unsensed toe level on heel-off.

        While the foot pitches toe-down, the toes stay flat on the floor: the toe joint flexes
        by the foot's pitch (within its range), about the joint's flexion axis.
        """
        forward = R_world_foot[:, 0]
        pitch = np.arctan2(-forward[2], np.hypot(forward[0], forward[1]))
        axis, lower, upper = self._toe_flexion[joint]
        half = 0.5 * float(np.clip(max(pitch, 0.0), lower, upper))
        return np.concatenate([np.sin(half) * axis, [np.cos(half)]])

    def _initial_guess(self, tracked: np.ndarray) -> np.ndarray:
        q = self.model.neutral() if self._q_start is None else self._q_start.copy()
        return self._sensed_configuration(q, tracked)

    # ------------------------------------------------------------------ solving
    def step(self, frame: Frame) -> Pose:
        """Solve one frame.

        Args:
            frame: Targets; its time must increase from frame to frame.

        Returns:
            The solved :class:`Pose`.
        """
        start = time.perf_counter()
        s = self.settings
        tracked = self._set_targets(frame)
        first = self._q is None or self._time is None
        dt = 0.0 if first else float(frame.time - self._time)  # type: ignore[operator]
        if first:
            q = self._initial_guess(tracked)
            iterations = s.first_frame_iterations
            self.damping_task.set_reference(None)
            self.velocity_limit.set_previous(None, 0.0)
        else:
            # Warm start at the sensed pose: joints between two sensed segments already where
            # the targets put them, so one Gauss-Newton step is usually enough.
            q, p_sensed = self._sensed_pose(self._q, tracked)  # type: ignore[arg-type]
            iterations = s.max_iterations
            self.damping_task.set_reference(self._q)
            self.velocity_limit.set_previous(self._q, dt)
        q_warm = q.copy()
        self._set_persistence(q_warm, first)
        if not first and self._contact_ids:
            self._p_sensed = self._smooth(self._p_sensed, p_sensed)
            pitch = self._foot_pitch(self._q, tracked)  # type: ignore[arg-type]
            self._pitch = self._smooth(self._pitch, pitch)
            still = self._feet_still(frame)
            self._contacts = release_contacts(self._contacts, self._p_sensed, self.thresholds,
                                              frame.contacts, self._pitch, still,
                                              self._history[-1][1],
                                              self.support.placed_offsets(self._contacts.active))
            # a planted heel whose foot already rolls toe-down may rise (it still cannot slip),
            # unless its IMU says the foot stands still
            rising = self._heels & (pitch > np.radians(s.heel_rise_deg))
            if still is not None:
                rising &= still != 1.0
            # points held in the last solve and not in this one: their legs ease back
            self.easing.release(self.contact_constraint.active & ~self._contacts.active,
                                self._last_bend)
        else:
            rising = None
        if not first:
            self._ease_released_legs(dt)
        self.contact_constraint.set_anchors(self._contacts.active, self._contacts.anchors,
                                            rising)
        if not first and self._contacts.active.any():
            # ... and translated so that its planted points sit on their anchors on average.
            offset = self.support.follow(self._contacts.active, self._contacts.anchors,
                                         p_sensed, dt)
            q[:3] += offset
            p_warm = p_sensed + offset
        elif not first:
            self.support.lose_support()
        self.floor_limit.enabled = ~self._contacts.active | self.contact_constraint.free_z
        flight = not first and bool(self._contact_ids) and not self._contacts.active.any()
        tasks: list[Task] = [self.orientation_task, self.position_task, self.posture_task,
                             self.damping_task, self.persistence_task]
        if frame.root_position is not None:
            self.root_task.set_targets(np.asarray(frame.root_position, dtype=float)[None],
                                       [frame.root_position_weight])
            tasks.append(self.root_task)
        elif flight:
            p_root = self._q[:3] + self._root_velocity * dt + 0.5 * GRAVITY * dt**2  # type: ignore[index]
            self.root_task.set_targets(p_root[None], [s.ballistic])
            tasks.append(self.root_task)
        elif not first and self._contacts.active.any():
            tasks += self._support_tasks(q, p_warm)
        conf = self._configuration
        conf.update(q)
        done, relaxed = 0, False
        for done in range(1, iterations + 1):  # noqa: B007 - `done` is reported after the loop
            problem = self._problem(conf, tasks)
            try:
                solution = self._solve_step(problem)
            except SolverError as err:
                self._failures.append(f"t = {frame.time:.3f} s: {err}; kept the last step")
                relaxed = True
                break
            relaxed = relaxed or solution.relaxed
            conf.update(conf.integrate(solution.dq))
            if np.max(np.abs(solution.dq)) < s.step_tolerance:
                break  # planted points are then held exactly by the projection below
        relaxed = self._project_on_constraints(conf) or relaxed
        q = conf.q.copy()
        self._bent = self._sensed_bend(q_warm, q)
        if first:
            q = self._place_on_floor(q)
            conf.update(q)
        pose = self._finish_frame(frame, q, tracked, dt, first, start, done, relaxed)
        return pose

    def _set_persistence(self, q_warm: np.ndarray, first: bool) -> None:
        """Joints between two sensed segments stay bent as they were in the last frame.

        Contacts, limits and the support tasks bend joints away from what the sensors say
        (``q_warm``, the sensed pose); a soft task keeps that bend (:attr:`_bent`, tangent
        [rad]) from frame to frame, so it changes gradually when a constraint comes or goes.
        Joints with an unsensed side are left out: their warm start is the last solved angle,
        and keeping a change of it would keep a velocity.
        """
        s = self.settings
        weights = np.zeros(self.model.model.nv)
        weights[self._sensed_joints] = s.persistence
        self.persistence_task.weights = weights
        self.persistence_task.set_reference(
            None if first or s.persistence <= 0 or self._bent is None
            else pin.integrate(self.model.model, q_warm, self._bent))

    def _sensed_bend(self, q_warm: np.ndarray, q: np.ndarray) -> np.ndarray:
        """``q ⊖ q_warm`` (nv) on the joints between two sensed segments, zero elsewhere."""
        bent = np.zeros(self.model.model.nv)
        bent[self._sensed_joints] = pin.difference(self.model.model, q_warm,
                                                   q)[self._sensed_joints]
        return bent

    def _last_bend(self, segments: np.ndarray) -> np.ndarray:
        """How far the last solved pose turned ``segments`` (m,) from their sensed orientations.

        ``Log(R_world_sensed^T R_world_solved)`` (m, 3) [rad], in the segment frames.
        """
        data = self._sensed_data
        pin.forwardKinematics(self.model.model, data, self._q)
        ids = [self.orientation_task.frame_ids[i] for i in segments]
        R_solved = np.array([pin.updateFramePlacement(self.model.model, data, f).rotation
                             for f in ids]).reshape(-1, 3, 3)
        return log_so3(np.swapaxes(self._last_sensed[segments], 1, 2) @ R_solved)

    def _ease_released_legs(self, dt: float) -> None:
        """Legs that let go of the floor return to their sensed orientations gradually.

        Their orientation targets are the sensed ones turned by :attr:`easing`'s offsets; the
        contact detection has already used the sensed ones.
        """
        eased = self.easing.apply(self._sensed_targets, dt)
        if eased is not None:
            self.orientation_task.set_targets(eased, self.orientation_task.weights)

    def _support_tasks(self, q: np.ndarray, p_warm: np.ndarray) -> list[Task]:
        """The pelvis at its warm start plus the lag; swing feet led to their offsets.

        Args:
            q: The warm start (sensed pose on the support).
            p_warm: (k, 3) its contact points [m].
        """
        s = self.settings
        tasks: list[Task] = []
        lag = self.support.lag
        share = self.support.placed_share
        weight = (1.0 - share) * s.continuity + share * s.continuity_placed
        target = self.support.pelvis_target(q[:3])
        if weight > 0 and (lag.any() or self.support.lean.any()):
            self.root_task.set_targets(target[None], [weight])
            tasks.append(self.root_task)
        targets, weights = self.support.swing_targets(p_warm + lag + self.support.lean)
        if weights.any():
            self.swing_task.set_targets(targets, weights)
            tasks.append(self.swing_task)
        return tasks

    def _problem(self, conf: Configuration, tasks: list[Task]) -> QpProblem:
        """The QP of one Gauss-Newton step (compiled residuals when available)."""
        s = self.settings
        previous = self.velocity_limit.q_previous  # also the damping task's reference
        moved = None if previous is None else conf.difference(previous)
        bounds = self.velocity_limit.bounds(conf, moved)
        nv = self.model.model.nv
        if self._kinematics is None:
            ranges = self.joint_limits.linearise(self.joint_limits.angles(conf.q), None, nv)
            up, down = ranges.near(self.joint_limits.margin)
            floor = self.floor_limit.inequality(conf)
            self._lazy = _LazyRows(ranges, up, down, floor, bounds)
            return build_qp(conf, tasks, [ranges.inequality(up, down), floor],
                            [self.contact_constraint.equality(conf)], None, s.levenberg_marquardt)
        H, c, _, angles, E_inv, p_sites, J_sites = self._kinematics(
            conf.q, self.orientation_task.targets, self._geometry, *self._row_weights,
            self.posture_task.R_reference)
        H, c = H.copy(), c[:, 0].copy()
        P = p_sites.reshape(-1, 3)
        J = J_sites.reshape(-1, 3, nv)
        self.position_task.add_rows(P[:-1], J[:-1], H, c)
        if self.root_task in tasks:
            self.root_task.add_rows(P[-1:], J[-1:], H, c)
        same = self.damping_task.q_reference is previous
        self.damping_task.add_objective(conf, H, c, moved if same else None)
        self.persistence_task.add_objective(conf, H, c)
        Pc, Jc = P[self._contact_rows], J[self._contact_rows]
        if self.swing_task in tasks:
            self.swing_task.add_rows(Pc, Jc, H, c)
        ranges = self.joint_limits.linearise(angles.reshape(-1, 3), E_inv.reshape(-1, 3, 3), nv)
        up, down = ranges.near(self.joint_limits.margin)
        floor = self.floor_limit.rows(Pc, Jc)
        self._lazy = _LazyRows(ranges, up, down, floor, bounds)
        return assemble_qp(H, c, [ranges.inequality(up, down), floor],
                           [self.contact_constraint.rows(Pc, Jc)], None, s.levenberg_marquardt)

    def _solve_step(self, problem: QpProblem) -> QpSolution:
        """Solve a step's QP, adding the rows it left out only when the step needs them.

        The problem holds the limits of angles near a limit and no velocity bounds
        (few are ever active, and every row costs the QP solver time); a step that would cross
        another limit or a bound is solved again with those rows. A relaxed step is solved
        again with every row.
        """
        s = self.settings
        backend, tol = s.backend, s.limit_crossing_tolerance
        solution = solve_qp(problem, backend, s.qp)
        lazy = self._lazy
        lb, ub = lazy.bounds if lazy.bounds is not None else (None, None)
        for _ in range(s.limit_resolves):
            if solution.relaxed:
                lazy.up[:], lazy.down[:] = True, True
            crossed_up, crossed_down = lazy.ranges.crossed(solution.dq, tol)
            crossed_up &= ~lazy.up
            crossed_down &= ~lazy.down
            outside = lb is not None and ub is not None and problem.lb is None and bool(
                np.any(solution.dq < lb - tol) or np.any(solution.dq > ub + tol))
            if not (solution.relaxed or outside or crossed_up.any() or crossed_down.any()):
                return solution
            lazy.up |= crossed_up
            lazy.down |= crossed_down
            ranges = lazy.ranges.inequality(lazy.up, lazy.down)
            problem.G = np.vstack([ranges.G, lazy.floor.G])
            problem.h = np.concatenate([ranges.h, lazy.floor.h])
            if outside or solution.relaxed:
                problem.lb, problem.ub = lb, ub
            relaxed_before = solution.relaxed
            solution = solve_qp(problem, backend, s.qp)
            if relaxed_before:
                return solution
        return solution

    def _project_on_constraints(self, conf: Configuration) -> bool:
        """Remove the linearisation residual of the contacts with minimum-norm steps.

        The Gauss-Newton loop may stop while large steps (a target out of reach) still leave a
        second-order error on planted points; a few minimum-norm steps on the contact rows (or,
        if those do not converge, QPs with only the constraints and ``1/2 |dq|^2``) bring it
        under ``constraint_tolerance`` so planted feet never slide.

        Returns:
            True when a step had to be relaxed.
        """
        s = self.settings
        max_steps = s.projection_steps
        nv = self.model.model.nv
        q_start = conf.q.copy()
        for _ in range(max_steps):  # the residual is second order: minimum-norm steps suffice
            P = conf.positions(self._contact_ids)
            slide = self.contact_constraint.slide_m(conf, P)
            if not np.any(slide[np.isfinite(slide)] > s.constraint_tolerance):
                if self._above_floor(P):
                    return False
                break
            A, b = self.contact_constraint.equality(conf)
            conf.update(conf.integrate(np.linalg.lstsq(A, b, rcond=None)[0]))
        conf.update(q_start)
        relaxed = False
        for _ in range(max_steps):  # ... unless they fail: the QP with the limits
            slide = self.contact_constraint.slide_m(conf)
            if not np.any(slide[np.isfinite(slide)] > s.constraint_tolerance):
                break
            problem = build_qp(conf, [], [self.joint_limits.inequality(conf),
                                          self.floor_limit.inequality(conf)],
                               [self.contact_constraint.equality(conf)], None, 0.0)
            problem.H = np.eye(nv)
            try:
                solution = solve_qp(problem, s.backend, s.qp)
            except SolverError:
                return True
            relaxed = relaxed or solution.relaxed
            conf.update(conf.integrate(solution.dq))
        return relaxed

    def _above_floor(self, p_contacts: np.ndarray) -> bool:
        """No contact point (c, 3) [m] below the floor (beyond the constraint tolerance)."""
        z = p_contacts[:, 2]
        return bool(np.all(z >= self.settings.floor_z - self.settings.constraint_tolerance))

    def _place_on_floor(self, q: np.ndarray) -> np.ndarray:
        """First frame: lift or lower the body so its lowest contact point is on the floor."""
        conf = self._configuration
        conf.update(q)
        if not self._contact_ids:
            return q
        z = conf.positions(self._contact_ids)[:, 2]
        q = q.copy()
        q[2] += self.settings.floor_z - z.min()
        return q

    def _feet_still(self, frame: Frame) -> np.ndarray | None:
        """1 where each contact point's foot stands still by its IMU, 0 moving, NaN unknown."""
        if not frame.feet_still:
            return None
        out = np.full(len(self.contact_names), np.nan)
        for i, name in enumerate(self.contact_names):
            still = frame.feet_still.get(f"{'Left' if name.startswith('Left') else 'Right'}Foot")
            if still is not None:
                out[i] = float(still)
        return out

    def _smooth(self, previous: np.ndarray, current: np.ndarray) -> np.ndarray:
        """Exponential smoothing of the contact-detection signals (sensor noise is white)."""
        a = self.settings.detection_smoothing
        return a * previous + (1.0 - a) * current

    def _foot_pitch(self, q: np.ndarray, tracked: np.ndarray) -> np.ndarray:
        """Pitch [rad] (toe down positive) of the foot of each contact point.

        From the foot's target when tracked, else from the solved pose; NaN without a foot.
        """
        feet = self._contact_feet
        forward = np.full((len(feet), 3), np.nan)
        for i, k in enumerate(feet):
            if k < 0:
                continue
            R = (self.orientation_task.targets[k] if tracked[k]
                 else self.model.segment_rotation(q, self.model.segment_names[k]))
            forward[i] = R[:, 0]
        return np.arctan2(-forward[:, 2], np.hypot(forward[:, 0], forward[:, 1]))

    def _contact_positions(self, q: np.ndarray) -> np.ndarray:
        data = self._sensed_data
        pin.forwardKinematics(self.model.model, data, q)
        return np.array([pin.updateFramePlacement(self.model.model, data, f).translation
                         for f in self._contact_ids]).reshape(-1, 3)

    def _finish_frame(self, frame: Frame, q: np.ndarray, tracked: np.ndarray, dt: float,
                      first: bool, start: float, iterations: int, relaxed: bool) -> Pose:
        conf = self._configuration
        p_contacts = conf.positions(self._contact_ids)
        # a rising heel is held against slipping but no longer stands on the floor
        contacts_now = {n: bool(a and not r) for n, a, r in zip(
            self.contact_names, self._contacts.active, self.contact_constraint.free_z)}
        if self._contact_ids:
            if first:
                self._p_sensed = self._sensed_pose(q, tracked)[1]
                self._pitch = self._foot_pitch(q, tracked)
            self._history.append((frame.time, p_contacts))
            self.support.record(p_contacts, q[:3])
            t_old, p_old = self._history[0]
            self._contacts = touch_down(self._contacts, p_contacts, p_old, self._p_sensed,
                                        frame.time - t_old, self.thresholds, frame.contacts,
                                        self._pitch)
            if first:
                contacts_now = self._contacts.as_dict()
        if not first and dt > 0:
            self._root_velocity = (q[:3] - self._q[:3]) / dt  # type: ignore[index]
        self._q = q
        self._last_sensed = self._sensed_targets
        self._time = frame.time
        return Pose(self.model, float(frame.time), q, contacts_now,
                    time.perf_counter() - start, iterations, relaxed,
                    self._residual_source(q))

    def _residual_source(self, q: np.ndarray) -> Callable[[], dict[str, dict[str, float]]]:
        """The residuals of the pose ``q`` against this frame's targets, computed on demand.

        The tasks replace (never modify) their target arrays, so keeping the arrays of this
        frame keeps its targets.
        """
        orientation, position = self.orientation_task, self.position_task
        targets = (self._sensed_targets, orientation.weights, position.targets,
                   position.information, self.contact_constraint.active,
                   self.contact_constraint.anchors, self.contact_constraint.free_z)
        model = self.model.model
        names = self.contact_names

        def residuals() -> dict[str, dict[str, float]]:
            R, w, p, info, active, anchors, free_z = targets
            o, pos = copy.copy(orientation), copy.copy(position)
            o.targets, o.weights, pos.targets, pos.information = R, w, p, info
            contact = copy.copy(self.contact_constraint)
            contact.set_anchors(active, anchors, free_z)
            conf = Configuration(model, q)
            slide = contact.slide_m(conf)
            return {
                "orientation_deg": o.errors_deg(conf),
                "position_m": pos.errors_m(conf),
                "contact_slide_m": {n: float(d) for n, d in zip(names, slide)
                                    if np.isfinite(d)},
            }

        return residuals

    def solve(self, frames: Iterable[Frame], progress: bool = False,
              total: int | None = None,
              after_step: Callable[[Solver, Pose, int, float], None] | None = None) -> Motion:
        """Solve a sequence of frames from scratch.

        Args:
            frames: Frames in time order.
            progress: Show a progress bar (tqdm).
            total: Number of frames, for the progress bar.
            after_step: Called as ``after_step(solver, pose, k, dt)`` after frame ``k`` (e.g.
                :meth:`ikfusion.correction.DriftCorrection.after_frame`).

        Returns:
            The :class:`Motion`.
        """
        self.reset()
        poses: list[Pose] = []
        previous = None
        for k, frame in enumerate(tqdm(frames, total=total, disable=not progress,
                                       unit="frame")):
            poses.append(self.step(frame))
            if after_step is not None:
                dt = 0.0 if previous is None else float(frame.time - previous)
                after_step(self, poses[-1], k, dt)
            previous = frame.time
        warnings = list(self._kinematics.warnings) if self._kinematics is not None else []
        if self._failures:
            warnings.append(f"{len(self._failures)} frame(s) where no QP backend could solve a "
                            f"step (first: {self._failures[0]})")
        relaxed = sum(p.relaxed for p in poses)
        if relaxed:
            warnings.append(f"{relaxed} frame(s) needed relaxed constraints (a planted foot "
                            "out of reach within the ranges of motion)")
        return Motion.from_poses(self.model, poses, self.contact_names, warnings)

    def frames_from_targets(self, times: Sequence[float],
                            orientations: dict[str, np.ndarray]) -> list[Frame]:
        """Frames from per-segment orientation arrays ``{segment: (N, 3, 3)}``."""
        return [Frame(float(t), {n: R[k] for n, R in orientations.items()})
                for k, t in enumerate(times)]
