"""Drift correction: bringing an inertial body to absolute tag positions (from UWB).

Inertial tracking chains contacts and drifts a little each step; UWB tags say where the head and
feet are. The correction compares, after each frame, the solved tag sites with the measured
positions (horizontal error, weighted by the measurements' covariances) and acts on the feet:

* ``slide``: every planted point is moved toward the correction at once (a first-order lag of
  ``time_constant``); the body follows at once, planted feet slide. What the contacts leave
  free is coupled to the tags as in ``no-slide`` (swing feet pulled, the ballistic path pulled
  in flight, feet and holds whose tags run away let go): sliding alone left a foot held in the
  air while its tag ran away, and a body in flight trailing its tags.
* ``no-slide``: planted points never move; the tag fixes are soft position tasks of each frame's
  QP on what the contacts leave free (swing feet; in flight they move the solver's ballistic
  path of the whole body) at a bounded rate (:mod:`.tag_tasks`); each swing foot is also led
  toward the mean correction (at most ``max_step`` per step), the pelvis leans toward it a
  little and follows each foot it is handed to gradually
  (:class:`ikfusion.ik.support.SupportFollower`), so the body walks (runs, jumps) into place
  step by step without a jump. A foot whose tag runs away from where it stands, and every held
  point when the head's tag runs away from the held body, are let go (:mod:`.tag_release`).
* ``off``: tags are only reported.

A heading drift of the sensors (a magnetically disturbed area) makes the body walk the wrong
way, which position corrections alone chase for ever. So the direction the tags travelled over
the last ``heading_window`` seconds is compared with the direction the solved tag sites
travelled; when both moved far enough, their angle is the heading error, and the solver's
orientation targets are turned toward it at a bounded rate (``slide`` and ``no-slide``). Fixes
whose covariance leaves the travel's direction uncertain are not compared (a causal filter
converging back after an outage reports its convergence as travel); back from an outage, half
a window of clean travel is compared rather than waiting for a whole one, since the body walks
the wrong way until its heading is turned back.

The first fix places the body in the tag frame at once (there is nothing to slide yet); in
``no-slide``, until the body's first step (the same feet planted) it keeps following the fixes,
which settle as the tag filters converge (a causal filter's first fix can be centimetres off,
and nothing else moves a standing body). The frames solved before are moved by these offsets
afterwards (:meth:`DriftCorrection.place_start`), so the whole motion is in the tag frame.
Heights come from the floor, so only the horizontal error is corrected.

In ``slide`` and ``no-slide``, stretches where a solved tag site stays more than ``far_distance``
from its fix for longer than ``far_duration`` are reported (:mod:`.far_from_tags`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from ..ik.frame import Frame
from ..ik.pose import Motion, Pose
from ..ik.solver import Solver
from ..ik.world_offset import WorldOffset
from ..settings_files import ShippedSettings
from .far_from_tags import FarInterval, far_intervals
from .tag_release import BodyRelease, FootRelease
from .tag_tasks import (
    BodyPull,
    SolvedTags,
    SwingClock,
    TagTaskSettings,
    bend_scale,
    body_targets,
    column_bend,
    feet_drift,
    flight_pull,
    horizontal_forward,
    planted_feet,
    sensed_bend_scale,
    tag_targets,
)

#: Correction modes.
MODES = ("off", "slide", "no-slide")


@dataclass
class SiteFixes:
    """Measured positions of model sites on the frame times.

    Attributes:
        site: Model site carrying the tag (``HeadTop``, ``LeftFootTop``, ``RightFootTop``).
        p_world: (N, 3) positions [m], NaN where there is no fix.
        cov: (N, 3, 3) their covariances [m^2].
    """

    site: str
    p_world: np.ndarray
    cov: np.ndarray


@dataclass(frozen=True)
class CorrectionSettings(ShippedSettings):
    """Thresholds of the drift correction, all from ``configs/correction.yaml``.

    Attributes:
        time_constant: Lag of the ``slide`` correction [s].
        max_step: Largest offset of one step in ``no-slide`` [m].
        heading_window: Travel compared for the heading error [s].
        heading_travel: Both travels must exceed this for an estimate [m].
        heading_deadband_deg: Errors below this are left alone [deg] (the sensors' own noise).
        heading_rate_deg: Largest turn of the targets [deg/s].
        heading_length_ratio: Travels whose lengths differ by more than this factor are not
            compared (the fixes jumped or the body slid: no heading information).
        heading_time_constant: The turn closes the error with this lag [s].
        heading_sigma_deg: A travel whose direction the fixes' covariances at the window's
            ends leave more uncertain than this is not compared [deg] (a filter converging
            back after an outage reports its convergence as travel, with its covariance).
        tag_speed: The tag tasks move a site at most this fast [m/s].
        tag_weight: ... with the fixes' information scaled by this.
        tag_sigma: ... with this uncertainty [m] added to the fixes' ...
        tag_vertical: ... pulling heights too (else horizontally only).
        tag_time_constant: In flight the pelvis closes the gap to the tags with this lag [s] ...
        tag_flight_speed: ... moving at most this fast toward them [m/s] ...
        tag_flight_vertical: ... in height too when the head's tag has a fix.
        tag_onset: A swing foot's task grows to full weight over this much of its swing [s],
            and fades out over as long before its predicted touch-down.
        tag_body_joint_bend_deg: The head's pull fades to nothing as the largest turn of a
            joint between two sensed segments from its sensors reaches this [deg]
            (:func:`~.tag_tasks.sensed_bend_scale`).
        release_distance: A planted foot whose tag moved farther than this [m]
            is let go (:mod:`.tag_release`) ...
        release_speed: ... until its tag moves slower than this [m/s] (and a foot near the
            floor whose tag moves faster is not planted: it has not landed); a step of a fix faster
            than ``release_jump_speed`` [m/s] is a jump of the positioning, not a foot moving
            (nor a heading drift: such a window is not compared).
        far_distance: A tag site farther than this from its fix [m] ...
        far_duration: ... for longer than this [s] is reported.
    """

    time_constant: float
    max_step: float
    heading_window: float
    heading_travel: float
    heading_deadband_deg: float
    heading_rate_deg: float
    heading_length_ratio: float
    heading_time_constant: float
    heading_sigma_deg: float
    tag_speed: float
    tag_weight: float
    tag_sigma: float
    tag_vertical: bool
    tag_time_constant: float
    tag_flight_speed: float
    tag_flight_vertical: bool
    tag_onset: float
    tag_body_weight: float
    tag_body_onset: float
    tag_body_bend_deg: float
    tag_body_joint_bend_deg: float
    release_distance: float
    release_speed: float
    release_jump_speed: float
    far_distance: float
    far_duration: float

    shipped_file = "correction.yaml"
    what = "correction settings"


@dataclass
class DriftCorrection:
    """Per-frame correction of a solve by tag positions (see the module docstring).

    Attributes:
        fixes: The measured sites.
        mode: ``off``, ``slide`` or ``no-slide``.
        settings: The thresholds (:meth:`CorrectionSettings.load`).
        gap: (N,) remaining horizontal gap after each frame [m] (NaN without a fix).
        heading: (N,) accumulated heading correction after each frame [rad].
        distance: (n_fixes, N) horizontal distance of each solved tag site to its fix after
            each frame [m] (NaN without a fix).
        time: (N,) the frame times [s].
    """

    fixes: list[SiteFixes]
    mode: str
    settings: CorrectionSettings
    gap: np.ndarray = field(default_factory=lambda: np.zeros(0))
    heading: np.ndarray = field(default_factory=lambda: np.zeros(0))
    distance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    _placed: bool = False
    _placement: tuple[int, np.ndarray] | None = None
    _placed_total: np.ndarray = field(default_factory=lambda: np.zeros(2))  # placing moves [m]
    _slid: np.ndarray = field(default_factory=lambda: np.zeros(2))  # slide mode's moves [m]
    _body: list[bool] = field(default_factory=list)  # per fix: on the body, not on a foot
    _feet: list[str | None] = field(default_factory=list)  # per fix: the foot carrying it
    _foot_of_point: dict[str, str | None] = field(default_factory=dict)
    _anchors: dict[str, list[str]] = field(default_factory=dict)  # foot -> sites moved by its tag
    _last: SolvedTags | None = None  # what the next frame's tag tasks take from the last
    _release: list[FootRelease | None] = field(default_factory=list)  # per fix on a foot
    _body_release: list[BodyRelease | None] = field(default_factory=list)  # per fix on the body
    _swing: SwingClock = field(default_factory=SwingClock)  # each foot's time off the floor
    _body_pull: BodyPull | None = None  # the head's task faded in and out on the floor
    _shape_pull: BodyPull | None = None  # the head's shaping of the trunk, faded in and out
    _stance: set[str] = field(default_factory=set)  # feet planted since the placement
    _low: set[str] = field(default_factory=set)  # feet not planted, below enter_height

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"correction mode must be one of {', '.join(MODES)}, not "
                             f"{self.mode!r}")
        n = len(self.fixes[0].p_world) if self.fixes else 0
        self.gap = np.full(n, np.nan)
        self.heading = np.zeros(n)
        self.distance = np.full((len(self.fixes), n), np.nan)
        self.time = np.full(n, np.nan)
        self._solved = np.full((len(self.fixes), n, 2), np.nan)  # solved sites, horizontal
        self._placed_before = np.zeros((n, 2))  # placing moves before each frame's [m]

    def grow(self, n: int) -> None:
        """Room for at least ``n`` frames (a live stream's fixes are filled frame by frame).

        The fixes and the per-frame records are extended with NaN (no fix, nothing measured
        yet), by doubling so that a long stream grows them rarely.
        """
        size = len(self.gap)
        if n <= size:
            return
        extra = max(n, 2 * size, 64) - size
        for f in self.fixes:
            f.p_world = np.concatenate([f.p_world, np.full((extra, 3), np.nan)])
            f.cov = np.concatenate([f.cov, np.full((extra, 3, 3), np.nan)])
        self.gap = np.concatenate([self.gap, np.full(extra, np.nan)])
        self.heading = np.concatenate([self.heading, np.zeros(extra)])
        self.time = np.concatenate([self.time, np.full(extra, np.nan)])
        self.distance = np.concatenate(
            [self.distance, np.full((len(self.fixes), extra), np.nan)], axis=1)
        self._solved = np.concatenate(
            [self._solved, np.full((len(self.fixes), extra, 2), np.nan)], axis=1)
        self._placed_before = np.concatenate([self._placed_before, np.zeros((extra, 2))])

    def horizontal_error(self, pose: Pose, k: int) -> np.ndarray | None:
        """Information-weighted mean of (measured - solved) over the sites with a fix [m]."""
        info_sum, weighted = np.zeros((2, 2)), np.zeros(2)
        for f in self.fixes:
            p, C = f.p_world[k], f.cov[k]
            if not (np.isfinite(p).all() and np.isfinite(C).all()):
                continue
            info = np.linalg.inv(C[:2, :2] + 1e-9 * np.eye(2))
            info_sum += info
            weighted += info @ (p[:2] - pose.site_position(f.site)[:2])
        if not info_sum.any():
            return None
        return np.asarray(np.linalg.solve(info_sum, weighted))

    def after_frame(self, solver: Solver, pose: Pose, k: int, dt: float) -> None:
        """Compare frame ``k`` with the fixes and steer the solver's feet for the next frames."""
        world = solver.world  # what a correction moves (and, in flight, solver.ballistic)
        self._placed_before[k] = self._placed_total
        if len(self._body) != len(self.fixes):  # sites on the body, not on a foot
            topology = solver.topology
            self._feet = [topology.foot_of(f.site) for f in self.fixes]
            self._body = [foot is None for foot in self._feet]
            self._foot_of_point = {p: topology.foot_of(p) for p in solver.contact_names}
            self._anchors = {foot: [f.site] + [p for p in solver.contact_names
                                               if topology.site_segment[p] == foot]
                             for f, foot in zip(self.fixes, self._feet) if foot is not None}
            s = self.settings
            self._release = [None if foot is None else
                             FootRelease(s.release_distance, s.release_speed,
                                         s.release_jump_speed)
                             for foot in self._feet]
            self._body_release = [BodyRelease(s.release_distance, s.release_jump_speed)
                                  if foot is None else None for foot in self._feet]
        R_pelvis = pose.segment_rotation(solver.model.segment_names[0])
        heads = [solver.topology.site_segment[f.site] for f, b in zip(self.fixes, self._body)
                 if b]
        R_head = pose.segment_rotation(heads[0]) if heads else None
        self._last = SolvedTags(dict(pose.contacts),
                                np.array([pose.site_position(f.site) for f in self.fixes]),
                                {p: pose.site_position(p) for points in
                                 self._anchors.values() for p in points},
                                horizontal_forward(R_pelvis),
                                column_bend(R_pelvis, R_head) if R_head is not None else 0.0,
                                solver.sensed_bend())
        planted = planted_feet(self._last.contacts, self._foot_of_point)
        self._swing.update(self._feet, planted, dt)
        floor_z = solver.settings.floor_z
        heights = {foot: np.array([pose.site_position(p)[2] - floor_z for p, of in
                                   self._foot_of_point.items() if of == foot])
                   for foot in self._anchors}
        self._swing.update_landing(heights, planted, dt)
        self._low = {foot for foot, z in heights.items() if foot not in planted and len(z)
                     and float(z.min()) < solver.settings.enter_height}
        # A foot's release judges its site without the slides of planted points (slide mode): a
        # foot slid after its running-away tag is still a false hold. The body's release keeps
        # the solved site: its hold spans a whole walk, which the slides rightly close.
        p_own = self._last.p_sites - np.array([self._slid[0], self._slid[1], 0.0])
        for f, foot, release, p_site in zip(self.fixes, self._feet, self._release, p_own):
            if release is not None:
                release.update(foot in planted, f.p_world[k], f.cov[k], p_site, dt)
        held = any(self._last.contacts.values())
        for f, body_release, p_site in zip(self.fixes, self._body_release, self._last.p_sites):
            if body_release is not None:
                body_release.update(held, f.p_world[k], f.cov[k], p_site, dt)
        self.time[k] = pose.time
        shifted = world.shifted[:2]  # the sites' travel without the corrections' moves
        for i, f in enumerate(self.fixes):
            p_site = pose.site_position(f.site)
            self._solved[i, k] = p_site[:2] - shifted
            self.distance[i, k] = float(np.linalg.norm(f.p_world[k, :2] - p_site[:2]))
        if self.mode != "off" and self._placed:
            self._correct_heading(world, k, dt)
        flight = self._last.flight
        if self.mode != "off" and self._placed and flight:
            self._pull_flight(solver, k, dt)
        self.heading[k] = world.heading
        error = self.horizontal_error(pose, k)
        if error is None:
            return
        self.gap[k] = float(np.linalg.norm(error))
        delta = np.array([error[0], error[1], 0.0])
        if self.mode == "off":
            return
        if self._placed and planted != self._stance:
            self._stance = set()  # a foot lifted or landed: the body has moved since
        if not self._placed:
            self._stance = planted
            world.translate(delta)
            self._placed = True
            self._placement = (k, delta)
            self._placed_total = self._placed_total + delta[:2]
        elif self.mode == "no-slide" and self._stance:
            world.translate(delta)  # not a step yet: the placement follows the settling fixes
            self._placed_total = self._placed_total + delta[:2]
        elif self.mode == "slide":
            if not flight:  # in flight the tags move the ballistic path (above)
                slid = delta * min(1.0, dt / self.settings.time_constant)
                world.slide(slid)
                self._slid = self._slid + slid[:2]
        else:
            world.lead_steps(delta, self.settings.max_step)

    def frames(self, frames: Iterable[Frame]) -> Iterator[Frame]:
        """``frames`` shaped one by one by :meth:`shape`, lazily.

        Frame ``k`` of the iterable meets the fixes' row ``k``. Each frame is made when the
        solver asks for it, after :meth:`after_frame` of the one before: which feet are
        planted comes from there.
        """
        previous: float | None = None
        for k, frame in enumerate(frames):
            dt = 0.0 if previous is None else float(frame.time - previous)
            previous = float(frame.time)
            yield self.shape(frame, k, dt)

    def shape(self, frame: Frame, k: int, dt: float) -> Frame:
        """Frame ``k`` with the tag tasks of ``slide`` and ``no-slide`` (:mod:`.tag_tasks`).

        Called just before the frame's solve, after :meth:`after_frame` of the frame before
        (``dt`` [s] after it): which feet are planted and whether the body flies come from
        there. Outside flight the frame gets soft position tasks on the tag sites the contacts
        leave free (in flight the tags move the solver's ballistic path instead:
        :meth:`after_frame`, :func:`~.tag_tasks.flight_pull`); the points of feet let go
        (:mod:`.tag_release`) are hinted off the floor. ``off`` returns the frame unchanged,
        and so do the others until the first fix placed the body (or with ``dt`` <= 0). Offline
        (:meth:`frames`) and the causal stream (:class:`ikfusion.live.actor_stream.
        ActorStream`) both shape their frames here.
        """
        last = self._last
        if self.mode == "off" or not self._placed or last is None or dt <= 0:
            return frame
        s, tag_settings = self.settings, self._tag_settings()
        p_fix = np.array([f.p_world[k] for f in self.fixes])
        cov = np.array([f.cov[k] for f in self.fixes])
        hints = self._hints(frame)
        if self._body_pull is None or self._shape_pull is None:
            self._body_pull = BodyPull(s.tag_body_onset)
            self._shape_pull = BodyPull(s.tag_body_onset)
        p_body, cov_body = self._body_pull.held(p_fix, cov)
        # not while the body still stands where it was placed: its fixes are still settling
        has_fix = not self._stance and any(
            np.isfinite(p).all() for p, b in zip(p_fix, self._body) if b)
        planted = planted_feet(last.contacts, self._foot_of_point)
        drift = feet_drift(self._feet, p_fix, last.p_sites)
        # the trunk's shape is judged only while the body stands near its feet's tags: while a
        # gap closes, the body moves under the head and the head's fix says nothing of the shape
        near = drift is not None and float(np.linalg.norm(drift)) < s.far_distance
        shape, shape_weights = body_targets(
            [f.site for f in self.fixes], self._feet,
            p_body - (0.0 if drift is None else drift), cov_body, last.forward,
            self._shape_pull.update(has_fix and near, dt)
            * bend_scale(last.bend, np.radians(s.tag_body_bend_deg)), tag_settings)
        frame = replace(frame, shape_positions=shape, shape_weights=shape_weights,
                        shape_reach=s.tag_speed * dt)
        if last.flight:  # the legs are left to their sensors; the tags move the body's path
            self._body_pull.drop()
            return replace(frame, contacts=hints)
        positions, weights = tag_targets(
            self._feet, p_fix, cov, last, planted, self._anchors, tag_settings,
            self._swing.swung, self._swing.landing)
        body, body_weights = body_targets(
            [f.site for f in self.fixes], self._feet, p_body, cov_body, last.forward,
            self._body_pull.update(has_fix, dt)
            * bend_scale(last.bend, np.radians(s.tag_body_bend_deg))
            * sensed_bend_scale(last.sensed_bend, np.radians(s.tag_body_joint_bend_deg)),
            tag_settings)
        positions, weights = {**positions, **body}, {**weights, **body_weights}
        if not positions:
            return replace(frame, contacts=hints)
        return replace(frame, positions={**frame.positions, **positions},
                       position_weights={**frame.position_weights, **weights},
                       position_reach=s.tag_speed * dt, contacts=hints)

    def _tag_settings(self) -> TagTaskSettings:
        """The ``no-slide`` tag tasks' part of the settings."""
        s = self.settings
        return TagTaskSettings(s.tag_speed, s.tag_weight, s.tag_sigma, s.tag_vertical,
                               s.tag_time_constant, s.tag_onset, s.tag_flight_speed,
                               s.tag_flight_vertical, s.tag_body_weight)

    def _pull_flight(self, solver: Solver, k: int, dt: float) -> None:
        """In flight: move the solver's ballistic path toward frame ``k``'s tags.

        The body flies (and lands) on the solver's one path (:mod:`ikfusion.ik.ballistic`);
        the tags move it at a bounded rate (:func:`~.tag_tasks.flight_pull`).
        """
        last = self._last
        if last is None:
            return
        p_fix = np.array([f.p_world[k] for f in self.fixes])
        cov = np.array([f.cov[k] for f in self.fixes])
        pull = flight_pull(last.p_sites, self._body, p_fix, cov, dt, self._tag_settings())
        if pull is not None:
            solver.ballistic.shift(pull)

    def _hints(self, frame: Frame) -> dict[str, bool] | None:
        """The frame's contact hints with the points of released feet (or body) let go.

        A foot near the floor whose tag still travels faster than ``release_speed`` is not
        landing either (it is kept off the floor): planted early, while the solve lagged a
        run's flight, it held the body back until the head's tag let every point go, and the
        tags then flew the body to them while the true foot stood (issue #19: 9 cm of slide).
        Only near the floor, so that a foot swinging high leaves the solver's own rules for
        landing from a flight (which act when no hint is given) alone.
        After the head's tag let every point go, until a point is held again
        (:attr:`~.tag_release.BodyRelease.landing`), tag feet not near the floor are kept off
        it: unhinted, the solver plants the lowest point wherever it is (a spin kick's toe
        28 cm up, rising at 5 m/s, dragged the body 37 cm from its tags).
        """
        released = {foot for foot, r in zip(self._feet, self._release)
                    if r is not None and (r.released or (r.moving and foot in self._low))}
        body = any(r is not None and r.released for r in self._body_release)
        if any(r is not None and r.landing for r in self._body_release):
            # let go by the head's tag and not held since: only a foot near the floor lands
            released |= set(self._anchors) - self._low
        hints = dict(frame.contacts or {})
        for point, foot in self._foot_of_point.items():
            if (body or foot in released) and point not in hints:
                hints[point] = False
        return hints or None

    def far_from_tags(self) -> list[FarInterval]:
        """Stretches where a solved tag site stayed far from its fix (:mod:`.far_from_tags`).

        None with ``off``: the body is then not placed in the tags' frame at all.
        """
        s = self.settings
        if self.mode == "off":
            return []
        out: list[FarInterval] = []
        for f, d in zip(self.fixes, self.distance):
            out += far_intervals(f.site, self.time, d, s.far_distance, s.far_duration)
        return out

    def far_warnings(self) -> list[str]:
        """One warning per stretch of :meth:`far_from_tags` (``summary.json``, terminal)."""
        return [i.message(self.settings.far_distance) for i in self.far_from_tags()]

    def heading_error(self, k: int, dt: float) -> float | None:
        """Angle from the solved sites' inertial travel to the tags' travel over the window [rad].

        The angle of :meth:`heading_estimate`, None when there is none.
        """
        estimate = self.heading_estimate(k, dt)
        return None if estimate is None else estimate[0]

    def heading_estimate(self, k: int, dt: float) -> tuple[float, int] | None:
        """Heading error up to frame ``k`` [rad] and the frame its travel starts at.

        The median over the sites whose fix and solved position both moved at least
        ``heading_travel`` by lengths within ``heading_length_ratio`` of each other, whose
        fixes' covariances leave the travel's direction certain within ``heading_sigma_deg``
        (a causal filter converging back after an outage reports its convergence as travel,
        with a covariance as large), and whose fix did not step faster than
        ``release_jump_speed`` within the window (the positioning jumped: a jump across the
        travel turns it with hardly a change of length), the head's (body sites') only when it
        has one (swing feet are led by the no-slide correction); None when none did (standing,
        turning on the spot, a jump of the fixes, no fixes). The travel is taken over the last
        ``heading_window`` seconds, or, when no site qualifies there, over its second half: the
        fixes are back from an outage since less than a window, and the body walks the wrong
        way until its heading is turned back.
        """
        s = self.settings
        if dt <= 0:
            return None
        for window in (s.heading_window, 0.5 * s.heading_window):
            back = k - int(round(window / dt))
            if back < 0:
                return None
            angle = self._travel_angle(k, back, dt)
            if angle is not None:
                return angle, back
        return None

    def _travel_angle(self, k: int, back: int, dt: float) -> float | None:
        """:meth:`heading_estimate` over the travel from frame ``back`` to ``k`` [rad]."""
        s = self.settings
        angles, body = [], []
        for i, f in enumerate(self.fixes):
            measured = f.p_world[k, :2] - f.p_world[back, :2]
            solved = self._solved[i, k] - self._solved[i, back]
            if not (np.isfinite(measured).all() and np.isfinite(solved).all()):
                continue
            lengths = np.linalg.norm(measured), np.linalg.norm(solved)
            if min(lengths) < s.heading_travel:
                continue
            if max(lengths) > s.heading_length_ratio * min(lengths):
                continue  # a jump of the fixes, not a turn: heading drift keeps the length
            spread = np.sqrt(np.trace(f.cov[k, :2, :2]) + np.trace(f.cov[back, :2, :2]))
            if not spread <= np.tan(np.radians(s.heading_sigma_deg)) * min(lengths):
                continue  # the fixes' uncertainty, not the travel, would set the angle
            steps = np.linalg.norm(np.diff(f.p_world[back:k + 1, :2], axis=0), axis=1)
            if (steps > s.release_jump_speed * dt).any():
                continue  # the positioning jumped within the window (across its travel too)
            angles.append(np.arctan2(solved[0] * measured[1] - solved[1] * measured[0],
                                     solved @ measured))
            body.append(self._body[i])  # set by after_frame from the model's topology
        if any(body):  # swing feet are led by the no-slide correction: trust the head first
            angles = [a for a, b in zip(angles, body) if b]
        return float(np.median(angles)) if angles else None

    def _correct_heading(self, world: WorldOffset, k: int, dt: float) -> None:
        """Turn the solver's targets toward the heading error, at a bounded rate."""
        s = self.settings
        estimate = self.heading_estimate(k, dt)
        if estimate is None:
            return
        error, back = estimate
        # the travel was solved under the turn of mid-window; what was turned since is done
        error -= world.heading - self.heading[(back + k) // 2]
        if abs(error) < np.radians(s.heading_deadband_deg):
            return
        step = error * min(1.0, dt / s.heading_time_constant)
        rate = np.radians(s.heading_rate_deg)
        world.turn(float(np.clip(step, -rate * dt, rate * dt)))

    @property
    def placement(self) -> tuple[int, np.ndarray] | None:
        """(frame index, (3,) offset [m]) of the first fix's placement, None before it."""
        return self._placement

    def placement_lacking(self, k: int) -> np.ndarray:
        """Horizontal placing moves (2,) [m] that frame ``k`` was solved before.

        The first fix places the body (:meth:`after_frame`); while the body then stands without
        a step (the same feet planted), it follows the settling fixes: nothing else corrects
        a standing body, and it has not moved. A frame solved before these moves (frame ``j``'s
        move is solved into frame ``j + 1`` on) is moved by their sum afterwards.
        """
        return self._placed_total - self._placed_before[k]

    def place_start(self, motion: Motion) -> None:
        """Move the frames solved before the first fix by its offset (in place).

        Until a tag is first heard the body stands in the inertial frame; the first fix moves
        it into the tag frame (:meth:`after_frame`), and this moves the frames before, and the
        fix's own frame, along, so the motion does not start with a jump.
        """
        if self._placement is None:
            return
        k = self._placement[0]
        n = min(len(motion.q), len(self._placed_before))
        motion.q[:n, :2] += self._placed_total - self._placed_before[:n]
        self.gap[:k + 1] = np.nan  # measured before the placement
        self.distance[:, :k + 1] = np.nan
