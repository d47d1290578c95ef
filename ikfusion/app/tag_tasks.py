"""Tag fixes as soft position tasks of the solve: the no-slide correction through the whole body.

Planted contact points are hard constraints of each frame's QP, so a position task cannot move
a planted foot: what the tags can correct is everything the contacts leave free. Each frame,
the tag sites (``HeadTop``, ``LeftFootTop``, ``RightFootTop``) get soft position tasks toward
their fixes

* on a foot whose contact points were all off the floor in the last frame: a swing foot is
  led to where its tag says; it lands there, and the body follows it onto the next step.
  Its pull is bounded: a target farther than ``tag_speed * dt`` acts as if it were that far
  (:attr:`ikfusion.ik.tasks.PositionTask.reach`), so the leg bends toward it at a bounded rate
  and no joint jumps, however far behind the body fell;
* in flight (no point planted) the root translation is free and the legs and trunk are best
  left to their sensors: the tags move the solver's ballistic path of the pelvis instead
  (:func:`flight_pull`) toward where they put it, by at most ``tag_flight_speed * dt`` per frame,
  closing the gap with a lag of ``tag_time_constant``; horizontally, and in height too when
  the head's tag has a fix (``tag_flight_vertical``: its height is as good as its horizontal,
  and the sensed take-off alone put a jump's apex 16 cm off). It is the solver's one path, which
  lands where the sensed legs meet the floor; a second parabola of the tags' own landed
  elsewhere and the hips popped at the landing.

A tag on the body (the head), while a point is planted, pulls the head in the body's sagittal
plane with a small weight (:func:`body_targets`, faded in and out by :class:`BodyPull`): the
sensed pelvis, chest and head keep their orientations and the unsensed spine and neck share
the bend as the fix says (their even share put a bent-over head centimetres high); the
horizontal drift is the feet's business, and the pelvis leans toward the correction there
(:mod:`ikfusion.ik.support`). A hold the head's tag runs away from is false: all its points are
let go (:class:`ikfusion.app.tag_release.BodyRelease`) and the body flies to its tags.
Each foot task is weighted by its fix's information (inverse covariance, with ``tag_sigma``
added) scaled by ``tag_weight``, horizontally, and vertically only with ``tag_vertical``
(heights come from the floor and the legs).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

#: Where a tag site is: on the body (the head) or on one of the feet (the foot's name).
BODY = None


@dataclass(frozen=True)
class TagTaskSettings:
    """How tag fixes pull their sites.

    Attributes:
        speed: The correction moves a site at most this fast [m/s].
        weight: Scale of the information matrices.
        sigma: Uncertainty [m] of where the solved leg can put its tag, added to the fix's.
        vertical: Also pull heights (else horizontal only).
        time_constant: In flight the pelvis closes the gap to the tags with this lag [s].
        onset: A foot's task grows from nothing to full weight over this much of its swing
            [s] (0: at once), and fades out over as long before it lands.
        flight_speed: In flight the tags move the pelvis's path at most this fast [m/s]
            (None: ``speed``).
        flight_vertical: In flight a body tag (the head) moves the path's height too, even
            without ``vertical``.
        body_weight: Scale of a body tag's (the head's) 3-D information while a point is
            planted (0: no body task; :func:`body_targets`).
    """

    speed: float
    weight: float
    sigma: float
    vertical: bool
    time_constant: float
    onset: float = 0.0
    flight_speed: float | None = None
    flight_vertical: bool = False
    body_weight: float = 0.0


@dataclass(frozen=True)
class SolvedTags:
    """What the next frame's tag tasks take from a solved frame.

    Attributes:
        contacts: Contact point -> planted.
        p_sites: (n, 3) the tag sites [m].
        p_points: Site -> its position (3,) [m]: the feet's anchors (:func:`tag_targets`).
        forward: (3,) the body's horizontal forward direction (unit; :func:`body_targets`).
        bend: Angle between the pelvis's and the head's up axes [rad] (:func:`bend_scale`).
        sensed_bend: The largest angle by which the solve turned a joint between two sensed
            segments from the sensors' relative orientation [rad] (:func:`sensed_bend_scale`).
    """

    contacts: Mapping[str, bool]
    p_sites: np.ndarray
    p_points: Mapping[str, np.ndarray] = field(default_factory=dict)
    forward: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    bend: float = 0.0
    sensed_bend: float = 0.0

    @property
    def flight(self) -> bool:
        """No point was planted."""
        return not any(self.contacts.values())


def tag_information(cov: np.ndarray, settings: TagTaskSettings) -> np.ndarray:
    """The information matrix (3, 3) [1/m^2] of a fix with covariance ``cov`` (3, 3) [m^2].

    ``weight * (cov + sigma^2 I)^-1``: the fix's own covariance with the uncertainty of where
    the solved leg can put its tag added (its size, its sensors), so that a precise fix does
    not bend the ankle instead of moving the leg. Horizontal only (zero vertical row and
    column) unless ``vertical``.
    """
    axes = 3 if settings.vertical else 2
    info = np.zeros((3, 3))
    floor = (settings.sigma**2 + 1e-9) * np.eye(axes)
    info[:axes, :axes] = settings.weight * np.linalg.inv(cov[:axes, :axes] + floor)
    return info


def tag_targets(feet: Sequence[str | None], p_fix: np.ndarray, cov: np.ndarray,
                last: SolvedTags, planted: set[str], anchors: Mapping[str, Sequence[str]],
                settings: TagTaskSettings, swing: Mapping[str, float] | None = None,
                landing: Mapping[str, float] | None = None
                ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The swing feet's targets and information matrices of one frame.

    A foot's tag says where the foot is, not how it is turned (its sensor says that): so
    several sites of the foot segment (its ``anchors``: the tag site and the foot's own contact
    points) are pulled, each by the tag's gap (fix minus the last solved tag site), sharing the
    fix's information. The foot moves as a whole; the tag site alone would turn the foot about
    the ankle, against its sensor, and the turn would spring back at touch-down.

    The pull grows smoothly over the first ``onset`` [s] of a swing and fades out as smoothly
    over the last ``onset`` [s] before the foot is predicted to touch down (``landing``). Only
    the horizontal of a site is pulled, so part of the pull is taken up by turning the foot
    about its ankle (a heel below the ankle moves horizontally when the foot pitches); once the
    heel is planted it cannot, and the turn sprang back within a frame: an ankle pop at every
    heel strike while a gap closed. Faded out before the touch-down, the turn unwinds over the
    fade instead.

    Args:
        feet: Per tag, the foot carrying it (None: on the body).
        p_fix: (n, 3) the tags' fixes [m] (NaN: none).
        cov: (n, 3, 3) their covariances [m^2].
        last: The last solved frame (tag sites and anchors).
        planted: Feet with a planted point in the last frame.
        anchors: Foot -> the sites moved with its tag (positions in ``last.p_points``).
        settings: Weight, axes and onset.
        swing: Foot -> how long it has been off the floor [s] (missing: a full swing).
        landing: Foot -> predicted time to its touch-down [s] (missing: not coming down).

    Returns:
        ``positions`` site -> target (3,) [m] and ``weights`` site -> information (3, 3).
    """
    positions: dict[str, np.ndarray] = {}
    weights: dict[str, np.ndarray] = {}
    for foot, p, C, p_site in zip(feet, p_fix, cov, last.p_sites):
        if foot is BODY or foot in planted:
            continue
        if not (np.isfinite(p).all() and np.isfinite(C).all()):
            continue
        scale = (onset_scale((swing or {}).get(foot, np.inf), settings.onset)
                 * onset_scale((landing or {}).get(foot, np.inf), settings.onset))
        points = [q for q in anchors.get(foot, ()) if q in last.p_points]
        if scale <= 0.0 or not points:
            continue
        gap = np.asarray(p, dtype=float) - p_site
        info = scale / len(points) * tag_information(C, settings)
        for point in points:
            positions[point] = last.p_points[point] + gap
            weights[point] = info
    return positions, weights


def body_targets(sites: Sequence[str], feet: Sequence[str | None], p_fix: np.ndarray,
                 cov: np.ndarray, forward: np.ndarray, scale: float, settings: TagTaskSettings
                 ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The body tags' (the head's) targets and information matrices of a frame on the floor.

    While a point is planted the pelvis stands where the sensed legs put it and the sensed
    segments (pelvis, chest, head) keep their IMU orientations; what the sensors leave open
    between them is how the unsensed spine and neck share the bend. The even share of the
    bend (:class:`ikfusion.ik.tasks.EvenChainTask`) put a crouching head centimetres high and
    behind; the head's fix says where it is. Its task pulls in the body's sagittal plane only
    (along ``forward`` and vertically), where the column bends: sideways a pull only shears
    the column into an S. Its information is the fix's (with ``sigma`` added) scaled by
    ``body_weight * scale``, far below a sensed segment's weight: it bends the unsensed
    joints toward the fix and hardly turns a sensed segment; planted points are hard
    constraints, so it never moves them.

    Args:
        sites: Per tag, its site.
        feet: Per tag, the foot carrying it (None: on the body).
        p_fix: (n, 3) the tags' fixes [m] (NaN: none).
        cov: (n, 3, 3) their covariances [m^2].
        forward: (3,) the body's horizontal forward direction (unit; the pelvis's x axis).
        scale: Factor in [0, 1] of the weight (:class:`BodyPull` fades it in and out).
        settings: ``body_weight`` and ``sigma``.

    Returns:
        ``positions`` site -> target (3,) [m] and ``weights`` site -> information (3, 3).
    """
    positions: dict[str, np.ndarray] = {}
    weights: dict[str, np.ndarray] = {}
    if settings.body_weight <= 0.0 or scale <= 0.0:
        return positions, weights
    axes = np.array([forward, [0.0, 0.0, 1.0]])  # (2, 3) the sagittal plane's axes
    for site, foot, p, C in zip(sites, feet, p_fix, cov):
        if foot is not BODY or not (np.isfinite(p).all() and np.isfinite(C).all()):
            continue
        C_plane = axes @ C @ axes.T + (settings.sigma**2 + 1e-9) * np.eye(2)
        positions[site] = np.asarray(p, dtype=float)
        weights[site] = settings.body_weight * scale * axes.T @ np.linalg.inv(C_plane) @ axes
    return positions, weights


def feet_drift(feet: Sequence[str | None], p_fix: np.ndarray, p_sites: np.ndarray
               ) -> np.ndarray | None:
    """How far the body stands from where its feet's tags put it (3,) [m].

    The mean over the feet's tags with a fix of fix minus solved tag site, horizontally (the
    vertical 0: heights come from the floor and the legs). The legs' sensors place the feet
    under the pelvis; what the feet's tags add is the whole body's drift (planted feet alone,
    with the last drift held in flight, left the body's drift to the trunk's shape at every
    touch-down: the feet fell 10-20 cm behind their tags). A body tag's fix
    minus this is where that tag is over the body as it stands: the part of its gap the
    trunk's shape explains (:class:`ikfusion.ik.tasks.ColumnShapeTask`), the drift being the
    feet's business.

    Args:
        feet: Per tag, the foot carrying it (None: on the body).
        p_fix: (n, 3) the tags' fixes [m] (NaN: none).
        p_sites: (n, 3) the last solved tag sites [m].

    Returns:
        The drift (3,) [m], None when no foot's tag has a fix.
    """
    gaps = [p - p_site for foot, p, p_site in zip(feet, p_fix, p_sites)
            if foot is not BODY and np.isfinite(p).all()]
    if not gaps:
        return None
    drift = np.mean(gaps, axis=0)
    drift[2] = 0.0
    return np.asarray(drift)


def onset_scale(swung: float, onset: float) -> float:
    """Weight factor in [0, 1] of a foot's task ``swung`` [s] into its swing (or before landing).

    A smooth step (zero slope at both ends) over ``onset`` [s]: the pull starts without a kick
    when the foot lifts, and ends without one when it lands.
    """
    if onset <= 0.0 or swung >= onset:
        return 1.0
    x = max(swung, 0.0) / onset
    return x * x * (3.0 - 2.0 * x)


def time_to_touchdown(height: np.ndarray, v_z: np.ndarray) -> float:
    """When the first of a foot's points reaches the floor at its vertical speed [s].

    Args:
        height: (k,) the points' heights above the floor [m].
        v_z: (k,) their vertical velocities [m/s].

    Returns:
        The least ``height / -v_z`` over the descending points (0 for a point on or below the
        floor), infinity when none descends.
    """
    h = np.maximum(np.asarray(height, dtype=float), 0.0)
    v = np.asarray(v_z, dtype=float)
    down = np.isfinite(h) & np.isfinite(v) & (v < 0.0)
    return float(np.min(h[down] / -v[down])) if down.any() else float("inf")


def horizontal_forward(R_world_pelvis: np.ndarray) -> np.ndarray:
    """The pelvis's x axis (forward) on the floor (3,), unit; world x when it points up."""
    x = np.array([R_world_pelvis[0, 0], R_world_pelvis[1, 0], 0.0])
    length = float(np.linalg.norm(x))
    return x / length if length > 1e-6 else np.array([1.0, 0.0, 0.0])


def column_bend(R_world_pelvis: np.ndarray, R_world_head: np.ndarray) -> float:
    """Angle between the pelvis's and the head's z (up) axes [rad]: how bent the column is."""
    cos = float(np.clip(R_world_pelvis[:, 2] @ R_world_head[:, 2], -1.0, 1.0))
    return float(np.arccos(cos))


def bend_scale(bend: float, full: float) -> float:
    """Weight factor in [0, 1] of the head's pull with the column ``bend`` [rad] bent.

    How the unsensed joints share a bend moves the head in proportion to the bend, so its
    information grows with the bend squared: ``(bend / full)^2``, 1 from ``full`` [rad] on.
    An upright column has no share to get wrong; there the pull would only pass the fixes'
    noise and a causal filter's lag into the spine (a walk's head 1.3 -> 1.9 cm).
    """
    if full <= 0.0:
        return 1.0
    return min(1.0, (bend / full) ** 2)


def sensed_bend_scale(sensed_bend: float, bound: float) -> float:
    """Weight factor in [0, 1] of the head's pull with a sensed joint bent ``sensed_bend`` [rad].

    The pull acts through every joint the planted points leave free, so it also turns joints
    between two sensed segments away from their sensors (a lying body's hip). Such a bend is
    held only by the planted points of the moment: when they change, it snaps back in a frame.
    The factor falls along a smooth step from 1 with no bend to 0 at ``bound`` [rad] (about
    the sensors' own relative-orientation error), so the pull keeps working where the joints
    agree with their sensors but cannot store a large bend. ``bound`` <= 0: no bound.
    """
    if bound <= 0.0:
        return 1.0
    x = min(1.0, sensed_bend / bound)
    return 1.0 - x * x * (3.0 - 2.0 * x)


class BodyPull:
    """How much of its weight the body tags' task has, faded in and out [0, 1].

    It grows while the body stands (a point planted) with a fix of a body tag and shrinks
    when the fix is lost, each time over ``onset`` [s] along a smooth step, with the last fix
    held while it fades: the bend the task gives the unsensed column comes and goes
    gradually. A take-off drops it (:meth:`drop`: in flight the tags move the whole body's
    path, and a head pulled there bent the column against the path's own pull); after the
    landing it grows again from nothing.

    Args:
        onset: Time to grow from nothing to full weight, and back [s] (0: at once).
    """

    def __init__(self, onset: float) -> None:
        self.onset = onset
        self._ramp = 0.0  # linear in time, 0..1
        self._held: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # tag -> last fix, covariance

    def update(self, on: bool, dt: float) -> float:
        """The weight factor of the next frame after ``dt`` [s] with the pull ``on`` or off."""
        if self.onset <= 0.0:
            self._ramp = 1.0 if on else 0.0
        else:
            self._ramp = min(1.0, max(0.0, self._ramp + (dt if on else -dt) / self.onset))
        x = self._ramp
        return x * x * (3.0 - 2.0 * x)

    def drop(self) -> None:
        """No weight now (the body flies); it grows from nothing when the pull is on again."""
        self._ramp = 0.0

    def held(self, p_fix: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The fixes (n, 3) [m] and covariances (n, 3, 3) with each missing one the last held."""
        p_out, cov_out = np.array(p_fix, dtype=float), np.array(cov, dtype=float)
        for i, (p, C) in enumerate(zip(p_out, cov_out)):
            if np.isfinite(p).all() and np.isfinite(C).all():
                self._held[i] = (p.copy(), C.copy())
            elif i in self._held:
                p_out[i], cov_out[i] = self._held[i]
        return p_out, cov_out


class SwingClock:
    """How long each foot has been off the floor and how soon it lands [s], per solved frame.

    Attributes:
        swung: Foot -> time since it lifted [s] (0 while planted).
        landing: Foot -> predicted time to its touch-down [s] (:func:`time_to_touchdown`).
    """

    def __init__(self) -> None:
        self.swung: dict[str, float] = {}
        self.landing: dict[str, float] = {}
        self._z: dict[str, np.ndarray] = {}  # foot -> its contact points' last heights [m]

    def update_landing(self, heights: Mapping[str, np.ndarray], planted: set[str],
                       dt: float) -> None:
        """After a frame: each foot's contact points' heights above the floor (k,) [m].

        Within a swing the predicted touch-down only comes nearer: at least ``dt`` nearer
        each frame, sooner when the foot says so (a heel that slows just above the floor
        would otherwise push it back, and the pull would return for the landing).
        """
        for foot, z in heights.items():
            z = np.asarray(z, dtype=float)
            last = self._z.get(foot)
            self._z[foot] = z
            if foot in planted or last is None or last.shape != z.shape or dt <= 0.0:
                self.landing[foot] = float("inf")
                continue
            before = self.landing.get(foot, float("inf")) - dt
            self.landing[foot] = max(0.0, min(before, time_to_touchdown(z, (z - last) / dt)))

    def update(self, feet: Sequence[str | None], planted: set[str], dt: float) -> None:
        """After a frame: the feet in ``planted`` restart at 0, the others swung ``dt`` more."""
        for foot in feet:
            if foot is BODY:
                continue
            self.swung[foot] = 0.0 if foot in planted else self.swung.get(foot, 0.0) + dt


def flight_pull(p_sites: np.ndarray, body: Sequence[bool], p_fix: np.ndarray, cov: np.ndarray,
                dt: float, settings: TagTaskSettings) -> np.ndarray | None:
    """How far the tags move the pelvis's ballistic path in one frame of flight (3,) [m].

    The gap from a solved frame to where its tags put the pelvis (the information-weighted
    mean of fix minus solved site; body tags only when one has a fix, as the head moves with
    the pelvis more than a foot does), closed by ``dt / time_constant`` of it per frame and by
    at most ``flight_speed * dt``; horizontal unless ``vertical``, or ``flight_vertical`` and a
    body tag gives the gap (a foot's height in flight is its leg's, not the pelvis's; the
    landing height still bounds the path). In flight this moves the
    whole body and bends no joint, so its bound is the body's visible change of speed, higher
    than a swing foot's ``speed``. The solver's own path
    (:meth:`ikfusion.ik.ballistic.BallisticRoot.shift`) is moved by it, so the body flies and
    lands on one path, not on a parabola of the correction's.

    Args:
        p_sites: (n, 3) the solved tag sites [m].
        body: Per tag, on the body (not on a foot).
        p_fix: (n, 3) the same frame's fixes [m] (NaN: none).
        cov: (n, 3, 3) their covariances [m^2].
        dt: Time to the next frame [s].
        settings: Speed, lag and axes.

    Returns:
        The move (3,) [m], None without a fix.
    """
    ok = np.isfinite(p_fix).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    use = ok & np.asarray(body, dtype=bool)
    if not use.any():
        use = ok
    if not use.any() or dt <= 0.0:
        return None
    info_sum, weighted = np.zeros((3, 3)), np.zeros(3)
    for i in np.flatnonzero(use):
        info = np.linalg.inv(cov[i] + 1e-9 * np.eye(3))
        info_sum += info
        weighted += info @ (p_fix[i] - p_sites[i])
    gap = np.linalg.solve(info_sum, weighted)
    by_body = bool(np.asarray(body, dtype=bool)[use].any())
    if not (settings.vertical or (settings.flight_vertical and by_body)):
        gap[2] = 0.0
    gap *= min(1.0, dt / settings.time_constant) if settings.time_constant > 0 else 1.0
    step = (settings.speed if settings.flight_speed is None else settings.flight_speed) * dt
    length = float(np.linalg.norm(gap))
    if length > step:
        gap *= step / length
    return np.asarray(gap)


def planted_feet(contacts: Mapping[str, bool], foot_of: Mapping[str, str | None]) -> set[str]:
    """The feet with a planted point among ``contacts`` (point -> planted)."""
    return {foot for point, on in contacts.items() if on
            for foot in [foot_of.get(point)] if foot is not None}
