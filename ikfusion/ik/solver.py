"""The whole-body solver: each frame a few Gauss-Newton steps, each a QP in the tangent space.

Per frame, warm started from the previous frame:

* costs: segment orientations (IMU), site positions (UWB, markers), a posture prior on joints
  the sensors leave open, smoothness toward the previous frame, the bend of sensed joints away
  from their sensors kept from the previous frame (:mod:`.sensed_pose`), the pelvis across
  hand-overs and swing feet led by a correction (:mod:`.support`), and during flight a
  ballistic pelvis path (:mod:`.ballistic`, its take-off velocity kept by the pelvis
  accelerometer);
* constraints: anatomical ranges of motion (linearised), contact points in contact held at
  their touch-down anchors (no slip), contact points above the floor, velocity bounds.

Global translation without aiding comes from chaining contacts: the planted foot is the anchor
(:mod:`.contact_tracker`). A leg that lets go of the floor eases back to its sensors
(:mod:`.release`), so what the contact bent does not snap back in one frame. A drift
correction moves the body through :attr:`Solver.world` (:mod:`.world_offset`) only.

Where the steps live: targets :mod:`.frame_targets`, the QP of a step :mod:`.frame_problem`,
its lazy limit rows :mod:`.active_set` (solved in closed form when no limit binds,
:mod:`.equality_qp`), the projection onto the contacts and the floor
:mod:`.projection`, the residual report :mod:`.residuals`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np
from tqdm import tqdm

from ..errors import SolverError
from ..model.human_model import HumanModel
from ..model.topology import BodyTopology
from .active_set import solve_with_active_set
from .ballistic import BallisticRoot, sensor_lever
from .contact_flags import ContactFlags
from .contact_tracker import ContactTracker
from .equality_qp import ClosedFormHint
from .frame import Frame
from .frame_problem import FrameTasks, build_frame_problem, compiled_step, step_configuration
from .frame_targets import FrameTargets, TargetLoader
from .pose import Motion, Pose
from .projection import RangeRows, native_projection, place_on_floor, project_on_contacts
from .residuals import residual_source
from .sensed_pose import Persistence, SensedPose
from .settings import SolverSettings
from .step_ranges import StepRangeRows
from .tasks import Task
from .world_offset import WorldOffset


class SolvedFrame(NamedTuple):
    """What the next frame takes from a solved one (made every frame: a tuple).

    Attributes:
        time: Its time [s].
        q: Its configuration.
        R_sensed: (n, 3, 3) its sensed orientation targets.
        bent: (nv,) how far the solve bent the joints between two sensed segments away from
            the sensed pose [rad] (:class:`.sensed_pose.Persistence`).
        root_velocity: (3,) the pelvis velocity [m/s].
    """

    time: float
    q: np.ndarray
    R_sensed: np.ndarray
    bent: np.ndarray
    root_velocity: np.ndarray


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
        self.settings = s = replace(base, **overrides) if overrides else base
        self.model = model
        self.topology = BodyTopology.of(model)
        self.contact_names = model.sites_of_kind("contact") if s.contacts else []
        self.persistence = Persistence(model.model, s.persistence)
        self.tasks = FrameTasks.create(model, s, self.contact_names, self.persistence.task)
        self._contact_frames = self.tasks.contact.frame_ids
        self.sensed = SensedPose(model, self.topology, self.tasks.orientation.frame_ids,
                                 self._contact_frames)
        self.compiled = compiled_step(model, self.tasks, self.sensed.spec()) if s.compiled \
            else None
        if self.compiled is not None:
            self.sensed.use_compiled(self.compiled.kinematics, self.compiled.geometry)
        self.targets = TargetLoader(model, self.tasks, self.sensed, s)
        self.contacts = ContactTracker(model, self.topology, self.contact_names, s)
        self._contact_flags = ContactFlags(self.contact_names)
        self.world = WorldOffset(self.contacts.support)
        self.ballistic = BallisticRoot(s.takeoff_velocity_tau, sensor_lever(model))
        self._configuration = step_configuration(model, self.tasks, self.compiled)
        self._projection = native_projection(self._configuration, self.tasks.contact)
        self._range_rows: RangeRows = self.tasks.joint_range if self.compiled is None else \
            StepRangeRows(self.compiled.kinematics, self.compiled.geometry,
                          self.compiled.rate_rows, self.tasks.joint_range,
                          len(self.tasks.orientation.frame_ids))
        self.reset()

    def reset(self, q: np.ndarray | None = None) -> None:
        """Forget the previous frames (the next frame is solved from scratch, or from ``q``)."""
        self._q_start = None if q is None else np.asarray(q, dtype=float).copy()
        self._last: SolvedFrame | None = None
        self._failures: list[str] = []
        self._closed_form = ClosedFormHint()
        self.contacts.reset()
        self.world.reset()
        self.ballistic.reset()

    # ------------------------------------------------------------------ solving
    def step(self, frame: Frame) -> Pose:
        """Solve one frame.

        Args:
            frame: Targets; its time must increase from frame to frame.

        Returns:
            The solved :class:`Pose`.
        """
        start = time.perf_counter()
        self._apply_world_moves()
        targets = self.targets.load(frame, self.world.R_heading)
        if self._last is None:
            return self._first_step(frame, targets, start)
        last, tasks, contacts = self._last, self.tasks, self.contacts
        dt = float(frame.time - last.time)
        # Warm start at the sensed pose: joints between two sensed segments already where the
        # targets put them, so one Gauss-Newton step is usually enough.
        q, p_sensed = self.sensed.pose(last.q, targets.R_sensed, targets.tracked)
        tasks.damping.set_reference(last.q)
        tasks.velocity.set_previous(last.q, dt)
        tasks.joint_range.next_frame(dt)
        tasks.chain_share.set_previous(last.q)
        q_warm = q.copy()
        self.persistence.hold(q_warm, targets.sensed_joints, last.bent)
        if self._contact_frames:  # (none: nothing to carry, release, ease or hold)
            contacts.carry(frame, dt, self.world.R_heading, last.root_velocity, last.q)
            rising = contacts.release(
                frame, p_sensed, contacts.foot_pitch(last.q, targets.R_sensed, targets.tracked))
            eased = contacts.ease(tasks.contact.active,
                                  lambda legs: self.sensed.bend(last.q, last.R_sensed, legs),
                                  targets.R_sensed, dt, tasks.contact.free_z)
            if eased is not None:  # legs that let go return to their sensors gradually
                tasks.orientation.set_targets(eased, tasks.orientation.weights)
            self._hold_contacts(rising)
        offset = contacts.follow(p_sensed, dt)  # ... its planted points on their anchors
        a_root = self._root_acceleration(frame)
        active: list[Task] = self._base_tasks(frame)
        if offset is not None:
            q[:3] += offset
            if frame.root_position is None:
                active += contacts.support_tasks(q, p_sensed, offset, tasks.root, tasks.swing)
        elif frame.root_position is None and self._contact_frames:  # flight: ballistic pelvis
            # the sensed pose's lowest contact point on the floor bounds the pelvis height
            lowest_z = self.settings.floor_z + q[2] - float(np.min(p_sensed[:, 2]))
            p_root = self.ballistic.target(last.q[:3], dt, a_root, lowest_z, targets.R_root)
            tasks.root.set_targets(p_root[None], [self.settings.ballistic])
            active.append(tasks.root)
        q, iterations, relaxed = self._solve(frame, targets, q, active,
                                             self.settings.max_iterations)
        # a rising heel is held against slipping but no longer stands on the floor
        contacts_now = self._contact_flags(tasks.contact.active, tasks.contact.free_z)
        self._touch_down(frame, q)
        velocity = (q[:3] - last.q[:3]) / dt if dt > 0 else last.root_velocity
        self.ballistic.update(velocity, dt, a_root, offset is not None, targets.R_root)
        return self._finish(frame, targets, q, q_warm, velocity, contacts_now, start,
                            iterations, relaxed)

    def _first_step(self, frame: Frame, targets: FrameTargets, start: float) -> Pose:
        """The first frame: from the sensed pose at the neutral (or reset) configuration.

        Nothing is planted yet and nothing is kept from before; the solved body is put on the
        floor, and the contacts it stands on are planted.
        """
        tasks, contacts = self.tasks, self.contacts
        q_start = self.model.neutral() if self._q_start is None else self._q_start.copy()
        q = self.sensed.configuration(q_start, targets.R_sensed, targets.tracked)
        tasks.damping.set_reference(None)
        tasks.velocity.set_previous(None, 0.0)
        tasks.joint_range.next_frame(None)
        tasks.chain_share.set_previous(None)
        q_warm = q.copy()
        self.persistence.hold(q_warm, targets.sensed_joints, None)
        self._hold_contacts(None)
        q, iterations, relaxed = self._solve(frame, targets, q, self._base_tasks(frame),
                                             self.settings.first_frame_iterations)
        q = place_on_floor(self._configuration, q, self._contact_frames, self.settings.floor_z)
        self._configuration.update(q)
        if self._contact_frames:
            contacts.start(self.sensed.pose(q, targets.R_sensed, targets.tracked)[1],
                           contacts.foot_pitch(q, targets.R_sensed, targets.tracked))
        self._touch_down(frame, q)
        return self._finish(frame, targets, q, q_warm, np.zeros(3), contacts.state.as_dict(),
                            start, iterations, relaxed)

    def _root_acceleration(self, frame: Frame) -> np.ndarray | None:
        """The frame's pelvis acceleration [m/s^2] in the solver's world (heading corrected)."""
        a = frame.root_acceleration
        if a is None:
            return None
        R, a = self.world.R_heading, np.asarray(a, dtype=float)
        return a if R is None else R @ a

    def _apply_world_moves(self) -> None:
        """Apply the drift correction's moves of the solved state since the last frame."""
        for kind, delta in self.world.take_moves():
            self.contacts.move(kind, delta)
            if kind == "all" and self._last is not None:
                q = self._last.q.copy()
                q[:3] += delta
                self._last = self._last._replace(q=q)

    def _touch_down(self, frame: Frame, q: np.ndarray) -> None:
        """Plant the points that reached the floor at ``q`` (no kinematics without points)."""
        if self._contact_frames:
            positions = self._configuration.positions(self._contact_frames)
            self.contacts.touch_down(frame, positions, q[:3])

    def _hold_contacts(self, rising: np.ndarray | None) -> None:
        """Hold the planted points at their anchors (``rising`` heels horizontally only)."""
        if not self._contact_frames:
            return
        state, tasks = self.contacts.state, self.tasks
        tasks.contact.set_anchors(state.active, state.anchors, rising)
        tasks.floor.enabled = self.contacts.floor_points()  # (none far above the floor)

    def _base_tasks(self, frame: Frame) -> list[Task]:
        """The tasks of every frame, with the pelvis at its aiding position when it has one."""
        t = self.tasks
        active: list[Task] = [t.orientation, t.position, t.shape, t.posture, t.even_chain,
                              t.chain_share, t.damping, t.persistence]
        if frame.root_position is not None:
            t.root.set_targets(np.asarray(frame.root_position, dtype=float)[None],
                               [frame.root_position_weight])
            active.append(t.root)
        return active

    def _solve(self, frame: Frame, targets: FrameTargets, q: np.ndarray, active: list[Task],
               iterations: int) -> tuple[np.ndarray, int, bool]:
        """Gauss-Newton steps from ``q``, then the projection onto the contacts.

        Returns:
            The solved configuration, the steps taken and whether a step was relaxed.
        """
        s, conf = self.settings, self._configuration
        conf.update(q)
        done, relaxed = 0, False
        for done in range(1, iterations + 1):  # noqa: B007 - `done` is reported after the loop
            problem = build_frame_problem(conf, self.tasks, active, targets.row_weights,
                                          self.compiled, s.levenberg_marquardt)
            try:
                solution = solve_with_active_set(problem.qp, problem.rows, s.backend, s.qp,
                                                 s.limit_crossing_tolerance, s.limit_resolves,
                                                 self._closed_form)
            except SolverError as err:
                self._failures.append(f"t = {frame.time:.3f} s: {err}; kept the last step")
                relaxed = True
                break
            relaxed = relaxed or solution.relaxed
            conf.step_by(solution.dq)
            self.tasks.joint_range.took_step(solution.dq)
            if np.maximum.reduce(np.abs(solution.dq)) < s.step_tolerance:
                break  # planted points are then held exactly by the projection below
        t = self.tasks
        relaxed = project_on_contacts(conf, t.contact, t.floor, self._range_rows,
                                      self._contact_frames, s.constraint_tolerance,
                                      s.projection_steps, s.backend, s.qp,
                                      self._projection) or relaxed
        return conf.q.copy(), done, relaxed

    def _finish(self, frame: Frame, targets: FrameTargets, q: np.ndarray, q_warm: np.ndarray,
                root_velocity: np.ndarray, contacts_now: dict[str, bool], start: float,
                iterations: int, relaxed: bool) -> Pose:
        """Keep what the next frame needs; the :class:`Pose` of this one."""
        bent = self.persistence.bend(q_warm, q, targets.sensed_joints)
        self._last = SolvedFrame(float(frame.time), q, targets.R_sensed, bent, root_velocity)
        return Pose(self.model, float(frame.time), q, contacts_now,
                    time.perf_counter() - start, iterations, relaxed,
                    residual_source(self.model.model, self.tasks, targets.R_sensed, q))

    def sensed_bend(self) -> float:
        """How far the last solve turned a joint between two sensed segments from the sensors.

        The largest over those joints of the angle between the solved and the sensed relative
        orientation [rad] (what contacts, limits and soft tasks bent them by); 0 before the
        first frame.
        """
        return 0.0 if self._last is None else self.persistence.largest(self._last.bent)

    def solve(self, frames: Iterable[Frame], progress: bool = False,
              total: int | None = None,
              after_step: Callable[[Solver, Pose, int, float], None] | None = None) -> Motion:
        """Solve a sequence of frames from scratch.

        Args:
            frames: Frames in time order.
            progress: Show a progress bar (tqdm).
            total: Number of frames, for the progress bar.
            after_step: Called as ``after_step(solver, pose, k, dt)`` after frame ``k`` (e.g.
                :meth:`ikfusion.app.correction.DriftCorrection.after_frame`).

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
        return Motion.from_poses(self.model, poses, self.contact_names,
                                 self.warnings(sum(p.relaxed for p in poses)))

    def warnings(self, relaxed: int) -> list[str]:
        """What the user should know about the frames solved since :meth:`reset`.

        Args:
            relaxed: How many of them needed relaxed constraints.
        """
        warnings = list(self.compiled.kinematics.warnings) if self.compiled is not None else []
        if self._failures:
            warnings.append(f"{len(self._failures)} frame(s) where no QP backend could solve a "
                            f"step (first: {self._failures[0]})")
        if relaxed:
            warnings.append(f"{relaxed} frame(s) needed relaxed constraints (a planted foot "
                            "out of reach within the ranges of motion)")
        return warnings

    def frames_from_targets(self, times: Sequence[float],
                            orientations: dict[str, np.ndarray]) -> list[Frame]:
        """Frames from per-segment orientation arrays ``{segment: (N, 3, 3)}``."""
        return [Frame(float(t), {n: R[k] for n, R in orientations.items()})
                for k, t in enumerate(times)]
