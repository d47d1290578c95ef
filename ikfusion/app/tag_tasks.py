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

A tag on the body (the head) acts in flight only; while a foot stands it could only bend the
trunk away from its sensors, and the pelvis leans toward the correction there
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
    """

    speed: float
    weight: float
    sigma: float
    vertical: bool
    time_constant: float
    onset: float = 0.0
    flight_speed: float | None = None
    flight_vertical: bool = False


@dataclass(frozen=True)
class SolvedTags:
    """What the next frame's tag tasks take from a solved frame.

    Attributes:
        contacts: Contact point -> planted.
        p_sites: (n, 3) the tag sites [m].
        p_points: Site -> its position (3,) [m]: the feet's anchors (:func:`tag_targets`).
    """

    contacts: Mapping[str, bool]
    p_sites: np.ndarray
    p_points: Mapping[str, np.ndarray] = field(default_factory=dict)

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
