"""Loading a frame's targets into the solver's tasks.

Orientation targets (turned by the heading correction), assumed targets of open hinge parents
(a thigh between a sensed pelvis and shank), site position targets, and the posture prior
switched off on the joints between two sensed segments.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..model.human_model import HumanModel
from .assumed import AssumedTargets
from .compiled_inputs import read_only
from .frame import Frame
from .frame_problem import FrameTasks
from .sensed_pose import SensedPose
from .settings import SolverSettings
from .tasks import PositionTask


class FrameTargets(NamedTuple):
    """What a frame's targets say, as the solver's steps use it (made every frame: a tuple).

    Attributes:
        R_sensed: (n, 3, 3) the segments' orientation targets ``R_world_segment`` as sensed
            (before any release easing).
        tracked: (n,) segments with a target this frame.
        sensed_joints: Tangent columns of the joints between two tracked segments.
        row_weights: Per-row weights of the orientation task and the posture task.
    """

    R_sensed: np.ndarray
    tracked: np.ndarray
    sensed_joints: np.ndarray
    row_weights: tuple[np.ndarray, np.ndarray]

    @property
    def R_root(self) -> np.ndarray | None:
        """(3, 3) the root's (pelvis's) sensed ``R_world_pelvis``, None when it is untracked."""
        return self.R_sensed[0] if self.tracked[0] else None


class _Rows(NamedTuple):
    """What a set of tracked segment names decides (kept while the set stays the same).

    Attributes:
        rows: (k,) their rows among the segments.
        weights: (n,) the weights of a frame without weights (1 on those rows, 0 elsewhere;
            read-only).
        assumed: Whether a hinge parent is open then.
        stack: (k + 1, 3, 3) the frame's targets in its first rows (written every frame), an
            identity in the last.
        gather: (n,) each segment's row of ``stack`` (the last for an untracked one).
    """

    rows: np.ndarray
    weights: np.ndarray
    assumed: bool
    stack: np.ndarray
    gather: np.ndarray


@dataclass(frozen=True)
class _Weighting:
    """What a frame's orientation weights decide (kept while they stay the same).

    Attributes:
        weights: (n,) the orientation task's per-segment weights.
        tracked: (n,) segments with a target.
        sensed_joints: Tangent columns of the joints between two tracked segments.
        posture_weights: (joints,) the posture task's weights (0 on those joints).
        row_weights: Per-row weights of the orientation task and the posture task.
    """

    weights: np.ndarray
    tracked: np.ndarray
    sensed_joints: np.ndarray
    posture_weights: np.ndarray
    row_weights: tuple[np.ndarray, np.ndarray]


class TargetLoader:
    """Sets the tasks' targets from frames (see the module docstring).

    Args:
        model: The human model.
        tasks: The solver's tasks.
        sensed: The sensed pose (which joints link which segments).
        settings: The assumed-target weight and the hinge joints.
    """

    def __init__(self, model: HumanModel, tasks: FrameTasks, sensed: SensedPose,
                 settings: SolverSettings) -> None:
        self.model = model
        self.tasks = tasks
        self.sensed = sensed
        self.assumed_weight = settings.assumed
        segments = model.segment_names
        self._segment_index = {n: i for i, n in enumerate(segments)}
        self._site_index = {n: i for i, n in enumerate(model.site_names)}
        self.assumed = AssumedTargets(segments, model.ball_joints, settings.hinge_joints)
        self._posture_weights = tasks.posture.weights.copy()
        self._identities = np.tile(np.eye(3), (len(segments), 1, 1))
        # tracked names -> their rows, weights, open hinges and gather (:meth:`_new_rows`)
        self._rows: dict[tuple[str, ...], _Rows] = {}
        self._positions_set = True  # the position task starts without targets: clear it once
        self._shape_set = True  # ... and the shape task
        self._last_weighting: _Weighting | None = None
        self._last_key = b""  # the bytes of its weights

    def load(self, frame: Frame, R_heading: np.ndarray | None) -> FrameTargets:
        """Set the tasks' targets from ``frame``, orientations turned by ``R_heading``."""
        tasks = self.tasks
        names = tuple(frame.orientations)
        rows, w, assumed, stack, gather = self._rows.get(names) or self._new_rows(names)
        if names:  # the targets, then an identity: each segment's row gathered at once
            targets = frame.orientations_stacked
            if targets is None or len(targets) != len(names):
                targets = np.array(list(frame.orientations.values()), dtype=float)
            stack[:-1] = targets if R_heading is None else R_heading @ targets
            R = stack.take(gather, axis=0)  # (a new array: the task keeps it)
        else:
            R = self._identities.copy()
        weights = frame.orientation_weights
        if weights:  # the weights given (else 1 on every row: the one array of these rows)
            w = np.zeros(len(self._segment_index))
            w[rows] = [weights.get(n, 1.0) for n in names]
            assumed = self.assumed.any_open(w > 0)
        if assumed and self.assumed_weight > 0:  # open hinge parents (a thigh between pelvis
            w = w.copy()  # and shank; the rows' weights are read-only)
            for i, R_assumed in self.assumed.targets(R, w > 0):
                R[i], w[i] = R_assumed, self.assumed_weight
        tasks.orientation.set_targets(R, w, owned=True)  # R is this call's own array
        if frame.positions or self._positions_set:
            self._load_sites(self.tasks.position, frame.positions, frame.position_weights)
            self.tasks.position.reach = frame.position_reach
        self._positions_set = bool(frame.positions)
        if frame.shape_positions or self._shape_set:
            self._load_sites(self.tasks.shape, frame.shape_positions, frame.shape_weights)
            self.tasks.shape.reach = frame.shape_reach
        self._shape_set = bool(frame.shape_positions)
        weighting = self._weighting(tasks.orientation.weights)
        tasks.posture.weights = weighting.posture_weights
        return FrameTargets(tasks.orientation.targets, weighting.tracked,
                            weighting.sensed_joints, weighting.row_weights)

    def _new_rows(self, names: tuple[str, ...]) -> _Rows:
        """The rows of a new set of tracked ``names`` (a sensor dropped out or came back)."""
        for name in names:
            self.model.segment_frame_id(name)  # raises NameNotFound with the valid names
        rows = np.array([self._segment_index[n] for n in names], dtype=int)
        w = np.zeros(len(self._segment_index))
        w[rows] = 1.0
        w.setflags(write=False)
        stack = np.zeros((len(names) + 1, 3, 3))
        stack[-1] = np.eye(3)
        gather = np.full(len(w), len(names))
        gather[rows] = np.arange(len(names))
        made = self._rows[names] = _Rows(rows, w, self.assumed.any_open(w > 0), stack, gather)
        return made

    def _weighting(self, weights: np.ndarray) -> _Weighting:
        """What the orientation weights (n,) of a frame decide; set on the chain tasks.

        Worked out again only when the weights differ from the last frame's (a sensor that
        drops out or comes back): the arrays are the same from frame to frame (read-only).
        """
        last = self._last_weighting
        key = weights.tobytes()  # the same bytes: the same weights (np.array_equal, cheaper)
        if last is not None and key == self._last_key:
            return last
        tasks = self.tasks
        tracked = weights > 0
        tasks.even_chain.set_tracked(tracked)
        tasks.chain_share.set_tracked(tracked)
        both = self.sensed.both_tracked(tracked)
        posture_weights = np.where(both, 0.0, self._posture_weights)
        tasks.posture.weights = posture_weights
        weighting = _Weighting(weights.copy(), tracked, self.sensed.joint_v_cols[both].ravel(),
                               posture_weights,
                               (tasks.orientation.row_weights(), tasks.posture.row_weights()))
        for array in (weighting.weights, tracked, weighting.sensed_joints, posture_weights,
                      *weighting.row_weights):
            read_only(array)  # (their memory too: a compiled step keeps them in its slots)
        self._last_weighting, self._last_key = weighting, key
        return weighting

    def _load_sites(self, task: PositionTask, positions: Mapping[str, np.ndarray],
                    weights: Mapping[str, float | np.ndarray]) -> None:
        """Load site targets into ``task`` (sites without one get zero information)."""
        m = len(self._site_index)
        p = np.zeros((m, 3))
        info = np.zeros((m, 3, 3))
        for name, p_target in positions.items():
            if name not in self._site_index:
                self.model.site_frame_id(name)
            i = self._site_index[name]
            p[i] = p_target
            weight = np.asarray(weights.get(name, 1.0), dtype=float)
            info[i] = weight * np.eye(3) if weight.ndim == 0 else weight
        task.set_targets(p, info)
