"""Feet that cannot stand where they were planted: their tags say they move.

The inertial solve plants a contact point when its foot is low and slow in the sensed pose;
in running, jumps and cartwheels a foot is sometimes planted that is in the air, and the
planted point, a hard constraint, then holds the whole body back while the tags run away.
Nothing a soft task could pull would move it.

A foot's own tag tells: while the foot is planted its fix moves only as the solved foot turns
about its planted point (a heel rising onto the toe carries a tag on the instep 10 cm forward).
So when a foot is planted, the gap from its solved tag site to its fix is remembered; once that
gap has changed by more than ``distance`` (and three standard deviations of the fix's horizontal
noise), the foot is let go (a contact hint of the frames, :class:`ikfusion.ik.Frame`), and it
stays let go while its fix keeps moving faster than ``speed``. Drift of the solved body does not
enter: a planted point does not move in the solve, so the solved site moves only with the foot's
sensed orientation, and the part of a change that closes the gap (the first fix placing the
body) does not count (:func:`unclosed_change`). A fix that steps faster than ``jump_speed``
(faster than any foot moves: the positioning itself jumped, e.g. a reader came back) moves the
remembered gap with it instead of letting a standing foot go.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class FootRelease:
    """Tag-based release of one foot (see the module docstring).

    Attributes:
        distance: A planted foot's fix moved farther than this [m] from where it was ...
        speed: ... and the foot stays let go while its fix moves faster than this [m/s].
        jump_speed: A step of the fix faster than this [m/s] is a jump of the positioning, not
            a foot moving.
        released: The foot is let go in the next frames.
        moving: Its fix moved faster than ``speed`` in the last frame (not a jump): a foot
            that is not planted is still travelling, not landing
            (:meth:`ikfusion.app.correction.DriftCorrection.shape` keeps it off the floor).
    """

    distance: float
    speed: float
    jump_speed: float
    released: bool = False
    moving: bool = False
    _anchor: np.ndarray | None = None  # (2,) the gap [m] when the foot was planted
    _last: np.ndarray | None = field(default=None)

    def update(self, planted: bool, p_fix: np.ndarray, cov: np.ndarray, p_site: np.ndarray,
               dt: float) -> None:
        """After a frame: was the foot ``planted``, where are its fix and its solved tag site.

        Args:
            planted: A point of the foot is planted in the solved frame.
            p_fix: (3,) the fix [m] (NaN: none this frame).
            cov: (3, 3) its covariance [m^2].
            p_site: (3,) the solved tag site [m].
            dt: Time since the last frame [s].
        """
        if not (np.isfinite(p_fix).all() and np.isfinite(cov).all()):
            return
        p = np.asarray(p_fix[:2], dtype=float)
        gap = p - np.asarray(p_site[:2], dtype=float)
        step = 0.0 if self._last is None else float(np.linalg.norm(p - self._last))
        jumped = dt > 0 and step > self.jump_speed * dt
        if jumped and self._anchor is not None and self._last is not None:
            self._anchor = self._anchor + (p - self._last)
        moving = self._last is not None and dt > 0 and not jumped and step > self.speed * dt
        self._last, self.moving = p, moving
        if self.released:
            self.released = moving
            self._anchor = None
            return
        if not planted:
            self._anchor = None
            return
        if self._anchor is None:
            self._anchor = gap
            return
        noise = 3.0 * float(np.sqrt(max(np.trace(cov[:2, :2]), 0.0)))
        if float(np.linalg.norm(unclosed_change(self._anchor, gap))) > max(self.distance, noise):
            self.released = True
            self._anchor = None


@dataclass
class BodyRelease:
    """Contacts held while a body tag runs away from the solved body: all let go.

    A planted point is a hard constraint: a false hold (a foot planted that is in the air, a
    hand held while the body crawls on) keeps the whole body in place while the person moves,
    and no soft task can move it. The tag on the body (the head) tells: while the body holds
    on to the floor, the gap from the solved site to its fix stays what it was when the hold
    began (a lean moves both). When it has changed by more than ``distance`` (and three
    standard deviations of the noise of two fixes' difference) during one hold, the hold is
    false and every held point is let go. The change is judged horizontally, and also with
    the fix's rise above the solved site (:func:`risen`): a body held on the floor cannot
    rise with its head, while a take-off toe held past the take-off (a spinning pelvis's
    accelerometers miss the flight) pins the body down as the head's fix goes up. A fix
    sinking under the solved head is the legs' shape, not a hold, and does not count. Once
    let go, the body flies, and the tags move its path
    (:func:`ikfusion.app.tag_tasks.flight_pull`) until the gap (with the rise since the hold
    began) is below half ``distance``; then the points may be planted again where the sensed
    legs meet the floor.
    Until one is (``landing``), nothing says the body is back on the floor: a closed gap is
    not a landing, and a foot high in the air must not be planted just because it is the
    body's lowest point (:meth:`ikfusion.app.correction.DriftCorrection.shape` keeps the feet
    that are not near the floor off it).
    Only a change within a hold counts, and not the part of it that closes the gap (the
    correction walking the body toward its tags, after a jump of the positioning say): a slow
    inertial drift never lets a standing body go.

    Attributes:
        distance: The gap changed by more than this during a hold [m] (not closing it) ...
        jump_speed: A step of the fix faster than this [m/s] is a jump of the positioning:
            the gap's reference moves with it.
        released: The held points are let go in the next frames.
        landing: A release ended (the gap closed) and no point has been held since.
    """

    distance: float
    jump_speed: float
    released: bool = False
    landing: bool = False
    _anchor: np.ndarray | None = None  # (2,) the gap [m] when the hold began
    _anchor_z: float = 0.0  # its height (fix above solved site: positive) [m]
    _last: np.ndarray | None = field(default=None)

    def update(self, held: bool, p_fix: np.ndarray, cov: np.ndarray, p_site: np.ndarray,
               dt: float) -> None:
        """After a frame: did the body hold a point, the body tag's fix and solved site.

        Args:
            held: A contact point is planted in the solved frame.
            p_fix: (3,) the fix [m] (NaN: none this frame).
            cov: (3, 3) its covariance [m^2].
            p_site: (3,) the solved tag site [m].
            dt: Time since the last frame [s].
        """
        if held:
            self.landing = False
        if not (np.isfinite(p_fix).all() and np.isfinite(cov).all()):
            return
        p = np.asarray(p_fix[:2], dtype=float)
        gap = p - np.asarray(p_site[:2], dtype=float)
        step = 0.0 if self._last is None else float(np.linalg.norm(p - self._last))
        jumped = dt > 0 and step > self.jump_speed * dt
        self._last = p
        gap_z = float(p_fix[2] - p_site[2])
        if self.released:  # until the gap closed, the risen height too
            rise = risen(self._anchor_z, gap_z)
            self.released = float(np.hypot(np.linalg.norm(gap), rise)) > 0.5 * self.distance
            self.landing = not self.released
            self._anchor = None
            return
        if not held or jumped or self._anchor is None:  # a jump of the fixes starts anew
            self._anchor, self._anchor_z = (gap if held else None), gap_z
            return
        change = unclosed_change(self._anchor, gap)
        rising = np.append(change, risen(self._anchor_z, gap_z))
        # the change of the gap is the difference of two fixes: sqrt(2) times one's noise
        for moved, axes in ((change, 2), (rising, 3)):
            noise = 3.0 * float(np.sqrt(max(2.0 * np.trace(cov[:axes, :axes]), 0.0)))
            if float(np.linalg.norm(moved)) > max(self.distance, noise):
                self.released = True


def unclosed_change(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """The change from gap ``before`` to gap ``after`` (2,) [m] without its closing part.

    The part of the change along ``-before`` (the gap shrinking toward zero, as a correction
    closes it) is left out, up to the whole of ``before``; what remains is how the gap moved
    otherwise.
    """
    change = np.asarray(after, dtype=float) - before
    length = float(np.linalg.norm(before))
    if length <= 0.0:
        return change
    u = np.asarray(before, dtype=float) / length
    along = float(change @ u)
    return change - max(min(along, 0.0), -length) * u


def risen(before: float, after: float) -> float:
    """How far a fix rose above its solved site from height gap ``before`` to ``after`` [m].

    The gaps are the fix's height minus the site's. Only a rise counts (never below 0), and
    not the part of it that closes a gap the fix started below the site.
    """
    return max(after - max(before, 0.0), 0.0)
