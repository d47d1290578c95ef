"""Contact orchestration from frame to frame: which points are planted, and what follows.

Before a frame is solved, planted points that the frame's sensed pose lifts let go
(:func:`.contacts.release_contacts`, with the feet's stance from their IMUs), a planted heel
whose foot rolls toe-down may rise, the legs that let go ease back to their sensors
(:mod:`.release`) and the body is carried by its support (:mod:`.support`). After it is solved,
points that reached the floor are planted (:func:`.contacts.touch_down`). A frame flagged
airborne (its accelerometers in free fall, :mod:`ikfusion.imu.flight`) lets go of every point
and plants none: the solver then flies the pelvis on its ballistic path, and the first frame
back on the ground plants the points that reach the floor where they are (no pop).
"""

from __future__ import annotations

import functools
import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np

from ..model.human_model import HumanModel
from ..model.layout import TRUNK_CONTACT_SITES
from ..model.topology import BodyTopology
from .anchor_carry import AnchorCarry
from .anchor_settling import held_again
from .contact_clocks import contact_clocks
from .contacts import ContactState, ContactThresholds, release_contacts, touch_down
from .fast_math import any_true
from .foot_pitch import FootPitch
from .frame import Frame
from .frame_stance import FrameStance
from .landing_lag import unlagged_landings
from .point_bits import above, indices, point_bits
from .point_evidence import FrameEvidence
from .release import ANKLE, ReleaseEasing
from .sensed_evidence import Rules, python_evidence, sensing
from .settings import SolverSettings
from .support import SupportFollower
from .tasks import PositionTask, Task

#: A trunk point (``needs_rest``) this far [m] above the lowest contact point of the
#: sensed pose cannot reach the floor within a frame: it gets no floor row (standing, walking,
#: running cost nothing for the points of a lying body).
FAR_FROM_FLOOR = 0.3

_Array = np.ndarray | None


class ContactTracker:
    """The contact state of a solve and what depends on it (see the module docstring).

    Args:
        model: The human model.
        topology: Its :class:`BodyTopology` (feet and legs of the contact points).
        names: Contact point names (none: no contacts).
        settings: Thresholds, speeds and weights.
    """

    def __init__(self, model: HumanModel, topology: BodyTopology, names: Sequence[str],
                 settings: SolverSettings) -> None:
        s = settings
        self.model = model
        self.names = list(names)
        self.layout = topology.foot_layout(self.names)
        self._bits = point_bits(self.layout)
        self.thresholds = ContactThresholds.from_settings(s)
        self.settings = s
        segments = model.segment_names
        self._foot_names = [topology.foot_of(n) for n in self.names]
        # the pitch of a foot proper rules its heel or toe out; knees and palms have none
        # where a lying or sitting body rests (the trunk): planted only with its IMU's rest
        self._needs_rest = np.array([n in TRUNK_CONTACT_SITES for n in self.names], dtype=bool)
        self._needs_rest.setflags(write=False)
        self._feet = np.array([segments.index(f) if f is not None and steps else -1
                               for f, steps in zip(self._foot_names, self.layout.stepping)],
                              dtype=int)
        self._heel_rise, self._tilt = math.radians(s.heel_rise_deg), math.radians(s.tilt_deg)
        # the points of each foot, for the per-frame stance lookup
        self._points_of_foot = {f: np.array([i for i, g in enumerate(self._foot_names) if g == f])
                                for f in dict.fromkeys(self._foot_names) if f is not None}
        self._pitch_of = FootPitch(model, self._feet)  # :meth:`foot_pitch`
        self._stance = FrameStance(self.names, self._foot_names, self._bits)
        self._rest = self._bits.of(self._needs_rest)  # the trunk points, as bits
        rules = Rules(s.detection_smoothing, FAR_FROM_FLOOR, self.thresholds.enter_relative,
                      self.thresholds.leave_relative, self._tilt, indices(self._rest),
                      indices(self._bits.heels), indices(self._bits.toes))
        self._sense = sensing(rules, len(self.names)) or functools.partial(python_evidence, rules)
        self._clocks = contact_clocks(len(self.names))  # (None: NumPy's, without a compiler)
        self._all = (1 << len(self.names)) - 1  # every point, as bits
        self.support = SupportFollower(self.layout, s.lag_speed, s.lag_max, s.swing_speed,
                                       s.lean_max, s.lean_speed, s.touchdown_confirm,
                                       self.thresholds.floor_z)
        legs = [np.array([segments.index(g) for g in topology.limb(f)] if f else [], dtype=int)
                for f in self._foot_names]
        self.easing = ReleaseEasing(legs, len(segments), np.radians(s.ease_speed_deg))
        self.carrier = AnchorCarry(model, self.names, self.layout,
                                   [topology.site_segment[n] for n in self.names],
                                   self._points_of_foot, s.release_speed)
        self.reset()

    def reset(self) -> None:
        """No point planted, no history."""
        self.state = ContactState.empty(self.names)
        self._history: deque[tuple[float, np.ndarray]] = deque(
            maxlen=max(2, self.settings.speed_window + 1))
        self._p_sensed = np.zeros((len(self.names), 3))
        self._pitch = np.zeros(len(self.names))
        self.far_from_floor = np.zeros(len(self.names), dtype=bool)
        self._far = 0  # far_from_floor's bits
        self._on_of = (self.state.active, 0)  # :meth:`planted`'s array and its bits
        self._rows_of: tuple[np.ndarray | None, list[list[float]]] = (None, [])  # anchors' rows
        self._v_sensed: np.ndarray | None = None
        self._rising = 0  # the planted heels release() let rise (bits: :mod:`.point_bits`)
        # the frame being solved's feet still, points moving and masks (touch_down reuses them)
        self._evidence: tuple[Frame, _Array, _Array, FrameEvidence] | None = None
        # the points the body last stood on; the points and lag of the last take-off
        self._stood, self._flown = self.state.active, (self.state.active, np.zeros(3))
        self.support.reset()
        self.easing.reset()
        self.carrier.reset()

    # ------------------------------------------------------------------ world moves
    def move(self, kind: str, delta: np.ndarray) -> None:
        """Move the anchors by ``delta`` (3,) [m]: ``"planted"`` ones, or ``"all"`` with history."""
        if kind == "planted":
            anchors = self.state.anchors.copy()
            anchors[self.state.active] += delta
            self.state = replace(self.state, anchors=anchors)
            return
        self.state = replace(self.state, anchors=self.state.anchors + delta)
        self._history = deque(((t, p + delta) for t, p in self._history),
                              maxlen=self._history.maxlen)

    def carry(self, frame: Frame, dt: float, R_heading: np.ndarray | None,
              v_body: np.ndarray, q: np.ndarray | None = None) -> None:
        """Points sliding by their foot IMU carry their anchors, the body its heels' (glide)."""
        if (anchors := self.carrier.carry(self.state, frame, dt, R_heading, v_body, q)) is not None:
            self.support.carry_held(self.carrier.glide(anchors - self.state.anchors))
            self.state = replace(self.state, anchors=anchors)

    # ------------------------------------------------------------------ per frame
    def foot_pitch(self, q: np.ndarray, R_world_sensed: np.ndarray,
                   tracked: np.ndarray) -> np.ndarray:
        """Pitch [rad] (toe down positive) of the foot of each contact point.

        From the foot's sensed target when tracked, else from ``q``; NaN without a foot
        (:class:`.foot_pitch.FootPitch`).
        """
        return self._pitch_of(q, R_world_sensed, tracked)

    def start(self, p_sensed: np.ndarray, pitch: np.ndarray) -> None:
        """The first frame's sensed contact points (c, 3) [m] and foot pitches (c,) [rad]."""
        self._p_sensed, self._pitch = p_sensed, pitch

    def release(self, frame: Frame, p_sensed: np.ndarray,
                pitch: np.ndarray) -> np.ndarray | None:
        """Let go of the points this frame's sensed pose lifts; plant those of still feet.

        Args:
            frame: The frame (contact hints, feet stance).
            p_sensed: (c, 3) contact points of its sensed pose [m] (any translation).
            pitch: (c,) foot pitch of each point [rad] (:meth:`foot_pitch`).

        Returns:
            (c,) planted heels that may rise (held against slipping only), None without
            contact points.
        """
        if not self.names:
            return None
        dt = frame.time - self._history[-1][0]  # the last solved frame's (smoothed) sensed pose
        # sensor noise is white: smooth the evidence (read-only: every rule of the frame reads it)
        sensed = self._sense(self._p_sensed, self._pitch, p_sensed, pitch, dt)
        self._p_sensed, self._pitch, step = sensed.p, sensed.pitch, sensed.step
        self._v_sensed, self._far = sensed.velocity, sensed.far
        self.far_from_floor = self._bits.mask(self._far)  # (read-only, shared)
        (still, stance), moving = self._stance.feet_still(frame), self._stance.points_moving(frame)
        th = self.thresholds
        evidence = FrameEvidence(sensed.height_rel, sensed.tilted, *stance, self._rest,
                                 sensed.high, sensed.low)
        self._evidence = (frame, still, moving, evidence)
        tip = self.carrier.tip_speed  # lone toes' tips sliding (0: none, the usual frame)
        bits, on = self._bits, self.planted()  # (:mod:`.point_bits`)
        # the placed offsets matter only while two feet are planted (release_contacts's drift)
        two_feet = on & bits.other_foot(on) or th.leave_distance < 0
        self.state = release_contacts(
            self.state, self._p_sensed, th, self._hints(frame), self._pitch, still,
            self._history[-1][1],
            self.support.placed_offsets(on) if two_feet else None,
            layout=self.layout, points_moving=self.carrier.relative_motion(self.state, moving),
            needs_rest=self._needs_rest, v_sensed=self._v_sensed, step_sensed=step,
            toe_off=tip > th.enter_speed if any_true(tip) else None, evidence=evidence, on=on)
        # a planted heel whose foot already rolls toe-down may rise (it still cannot slip),
        # unless its IMU says the foot stands still
        on = self.planted()
        rising = bits.heels & on & ~evidence.still
        if rising:
            rising &= above(pitch.tolist(), self._heel_rise, indices(rising))
        was, self._rising = self._rising, rising
        if again := was & ~rising & on:  # heels that rose in the last frame: held in height
            anchors = held_again(self.state.anchors, self._history[-1][1][:, 2], bits.mask(again),
                                 th.settle_speed * max(dt, 0.0), th.floor_z)
            self.state = replace(self.state, anchors=anchors)
        return bits.mask(rising)

    def ease(self, held: np.ndarray, bend: Callable[[np.ndarray], np.ndarray],
             R_world_sensed: np.ndarray, dt: float,
             free_z: np.ndarray | None = None) -> np.ndarray | None:
        """Legs of points ``held`` in the last solve and not now ease back to their sensors.

        So do the foot and shank (:data:`.release.ANKLE`) of heels held in height that rise now.

        Args:
            held: (c,) points held by the contact constraint in the last solve.
            bend: See :meth:`ReleaseEasing.release`.
            R_world_sensed: (n, 3, 3) this frame's sensed orientation targets.
            dt: Time since the last frame [s].
            free_z: (c,) those of them held horizontally only (None: none).

        Returns:
            The eased orientation targets (n, 3, 3), None when no leg eases.
        """
        if self.names:
            bits = self._bits
            on, was = self.planted(), bits.of(held)
            if was & ~on:
                self.easing.release(bits.mask(was & ~on), bend)
            if (up := was & on & self._rising) and (up := up & ~bits.of_optional(free_z)):
                self.easing.release(bits.mask(up), bend, ANKLE)
        return self.easing.apply(R_world_sensed, dt)

    def planted(self) -> int:
        """The planted points ``state.active`` as bits, worked out once per state's array.

        (A state's arrays are never written to: :class:`.contacts.ContactState`.)
        """
        active, on = self._on_of
        if active is not self.state.active:
            active = self.state.active
            self._on_of = (active, on := self._bits.of(active))
        return on

    def floor_points(self) -> np.ndarray:
        """(c,) read-only: the points the floor holds up this frame (one floor row each).

        Those not held at their anchors in height (free, or heels that :meth:`release` let
        rise) and not far above it (:attr:`far_from_floor`).
        """
        return self._bits.mask(self._all & ~(self.planted() & ~self._rising) & ~self._far)

    def follow(self, p_sensed: np.ndarray, dt: float) -> np.ndarray | None:
        """The support offset (3,) [m] putting the sensed pose on its anchors; None in flight."""
        if on := self.planted():
            self._stood, anchors = self.state.active, self.state.anchors
            if self._rows_of[0] is not anchors:  # (never written to, as ``planted``)
                self._rows_of = (anchors, anchors.tolist())
            return self.support.follow(on, self._rows_of[1], p_sensed, dt)
        if any_true(self._stood):  # the take-off: its lag is kept for the landing
            self._flown, self._stood = (self._stood, self.support.lag.copy()), self.state.active
        self.support.lose_support()
        return None

    def support_tasks(self, q: np.ndarray, p_sensed: np.ndarray, offset: np.ndarray,
                      root: PositionTask, swing: PositionTask) -> list[Task]:
        """The pelvis at its warm start plus the lag; swing feet led to their offsets.

        Args:
            q: The warm start (sensed pose on the support).
            p_sensed: (c, 3) the sensed pose's contact points [m] (:meth:`follow`'s; not
                written to after).
            offset: (3,) the support offset [m] (:meth:`follow`'s): the warm start's points
                are ``p_sensed + offset``, worked out when a swing foot is led.
            root: The pelvis position task (its targets are set here).
            swing: The swing-feet position task (its targets are set here).
        """
        s, support = self.settings, self.support
        tasks: list[Task] = []
        weight = (1.0 - (part := support.placed_share)) * s.continuity + part * s.continuity_placed
        target = support.pelvis_target(q[:3])
        if weight > 0 and support.moves_pelvis():
            root.set_target(target, weight)
            tasks.append(root)
        if not support.leads():  # the usual frame: no swing foot led
            support.keep_base(p_sensed, offset)
            return tasks
        targets, weights = support.swing_targets(support.led_points(p_sensed + offset))
        if any_true(weights):
            swing.set_targets(targets, weights)
            tasks.append(swing)
        return tasks

    def touch_down(self, frame: Frame, p_contacts: np.ndarray, p_root: np.ndarray) -> None:
        """After solving: plant the points that reached the floor (``frame``'s contact hints).

        ``p_contacts`` (c, 3), ``p_root`` (3,): the solved contact points and pelvis [m]; IMU
        only, a foot lands less the lag (even one its toes took off with: :mod:`.landing_lag`).
        """
        if not self.names:
            return
        self._history.append((frame.time, p_contacts))
        self.support.record(p_contacts, p_root)
        t_old, p_old = self._history[0]
        released, self._evidence = self._evidence, None
        still, moving, evidence = (released[1:] if released is not None and released[0] is frame
                                   else (self._stance.feet_still(frame)[0],
                                         self._stance.points_moving(frame), None))
        before = self.state.active
        self.state = touch_down(self.state, p_contacts, p_old, self._p_sensed,
                                frame.time - t_old, self.thresholds, self._hints(frame),
                                self._pitch, layout=self.layout, points_moving=moving,
                                foot_still=still, needs_rest=self._needs_rest,
                                v_sensed=self._v_sensed, evidence=evidence, on=self.planted(),
                                clocks=self._clocks)
        if frame.points_velocity:  # (none: no landing is unlagged)
            stood, lag = (before, self.support.lag) if any_true(before) else self._flown
            self.state = unlagged_landings(stood, self.state, self.layout, lag, frame)

    def _hints(self, frame: Frame) -> Mapping[str, bool] | None:
        """The frame's contact hints; in flight (``frame.airborne``) every point is free.

        A hint takes precedence for its own point only: a flight frame that hints one foot off
        (a foot its tag let go, :mod:`ikfusion.app.tag_release`) still frees the other foot.
        """
        if frame.airborne:
            return {**dict.fromkeys(self.names, False), **(frame.contacts or {})}
        return frame.contacts
