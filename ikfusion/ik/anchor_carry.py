"""Planted points carried along the floor by their foot IMU (IMU only, offline velocities).

A held heel whose foot IMU says it moves (landing while it still travels, as the heels of brisk
mocap walks do) would otherwise hold the body back by as much as it moves; without absolute
positions the IMU is the only witness. :class:`AnchorCarry` moves such anchors by the
velocity's integral over the frame and tells the release which carried points hold the body
as well as a still one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..imu.point_speed import floor_tip_slide
from ..model.human_model import HumanModel
from ..model.topology import FootLayout
from .contacts import ContactState
from .fast_math import any_true
from .frame import Frame


class AnchorCarry:
    """Carries the anchors of sliding feet, one solve at a time (:meth:`reset` between).

    Args:
        model: The human model (the toes' hinge geometry).
        names: Contact point names.
        layout: Their feet (:meth:`BodyTopology.foot_layout`).
        point_segments: The segment of each point.
        points_of_foot: Per foot, the indices of its points.
        release_speed: A point slides once its foot IMU says it moves faster than this [m/s].
    """

    def __init__(self, model: HumanModel, names: Sequence[str], layout: FootLayout,
                 point_segments: Sequence[str], points_of_foot: Mapping[str, np.ndarray],
                 release_speed: float) -> None:
        self.model = model
        self.names = list(names)
        self.layout = layout
        self._point_segments = list(point_segments)
        self._points_of_foot = dict(points_of_foot)
        self.release_speed = release_speed
        self.reset()

    def reset(self) -> None:
        """Nothing slides, no velocity of a last frame."""
        k = len(self.names)
        self.carried = np.zeros(k, dtype=bool)  # heels carried at their own velocity this frame
        self._slid = np.zeros((k, 2))  # each point's shift in the last frame [m] (0: none)
        #: toes held alone on their foot: how fast their tips slide this frame [m/s], else 0
        self.tip_speed = np.zeros(k)
        self._velocity_before: Mapping[str, np.ndarray] = {}
        #: carried, tip_speed and _slid of a frame where nothing slides (read-only zeros)
        self._nothing = (np.zeros(k, dtype=bool), np.zeros(k), np.zeros((k, 2)))
        for zeros in self._nothing:
            zeros.setflags(write=False)

    def carry(self, state: ContactState, frame: Frame, dt: float, R_heading: np.ndarray | None,
              v_body: np.ndarray, q: np.ndarray | None = None) -> np.ndarray | None:
        """The anchors (k, 3) [m] after this frame's slides, None when nothing slides.

        Per foot, when each of its planted points slides by its ``frame.points_velocity``
        (faster than ``release_speed`` horizontally, the velocity more horizontal than vertical:
        a point still landing or already lifting does not slide on the floor), they all move by
        the slowest one's horizontal velocity, averaged over the frame (the mean of this frame's
        and the last one's: a landing heel decelerates from 1.3 m/s to rest within 0.15 s, and
        this frame's velocity alone falls short by half the speed lost per frame, 1 cm per
        landing), times ``dt``. A point that slid in the last frame goes on sliding without
        those two thresholds while its velocity keeps its direction: the end of a landing
        heel's glide is slow and, integrated, tilted upward, yet the truth's heel still moves
        some millimetres.

        A heel slides at its own velocity. A toe's velocity by the IMU is its ball's, which
        moves while the toe stands when the foot pivots on its toes (kneeling down): a toe held
        alone (push-off) slides at what its hinge cannot explain on the floor
        (:func:`~ikfusion.imu.point_speed.floor_tip_slide`, from the last solved pose ``q``;
        without ``q`` toes are not carried), and a foot holding heel and toe is not carried. A
        shift against the travel of a body that moves (faster than ``release_speed``) is left
        out: a loaded foot is not dragged backwards by the body going forward, that is the
        velocity's integration error (a foot wrongly found still in the swing of a skip).
        Such a toe's tip speed, carried or not, is kept in :attr:`tip_speed` (the release's
        toe-off cue).

        Args:
            state: The contact state (its planted points and anchors; not changed).
            frame: The frame (its ``points_velocity``, world frame of the sensors [m/s]).
            dt: Time since the last frame [s].
            R_heading: The solver world's heading correction (applied to the velocities),
                None for none.
            v_body: (3,) the pelvis's velocity in the last frame [m/s].
            q: The last solved configuration (the toes' hinge geometry), None for none.
        """
        slid = self._slid
        before, self._velocity_before = self._velocity_before, frame.points_velocity
        if not frame.points_velocity or dt <= 0 or not any_true(state.active):
            self.carried, self.tip_speed, self._slid = self._nothing  # (the usual frame)
            return None
        k = len(self.names)
        self.carried, self.tip_speed, self._slid = (np.zeros(k, dtype=bool), np.zeros(k),
                                                    np.zeros((k, 2)))
        anchors = None
        for points in self._points_of_foot.values():
            held = points[state.active[points]]
            v_world = self._velocities(held, frame.points_velocity, before)
            toes = self.layout.below_foot[held]
            if v_world is None or (toes.any() and (not toes.all() or q is None)):
                continue
            sliding = bool(slid[held].any(axis=1).all())
            if not sliding and (np.abs(v_world[:, 2])
                                >= np.linalg.norm(v_world[:, :2], axis=1)).any():
                continue
            if toes.all() and q is not None:  # the ball's: what the toe's hinge cannot take up
                v_world = np.array([self._tip_slide(int(i), v, q, R_heading)
                                    for i, v in zip(held, v_world, strict=True)])
            speeds = np.linalg.norm(v_world[:, :2], axis=1)
            if toes.all() and q is not None:
                self.tip_speed[held] = speeds
            if not sliding and speeds.min() <= self.release_speed:
                continue
            shift = v_world[int(np.argmin(speeds)), :2] * dt
            if R_heading is not None:
                shift = R_heading[:2, :2] @ shift
            if sliding and float(shift @ slid[held[0]]) <= 0.0:  # it stopped (or turned back)
                continue
            if (float(shift @ v_body[:2]) < 0.0
                    and float(np.hypot(v_body[0], v_body[1])) > self.release_speed):
                continue
            anchors = state.anchors.copy() if anchors is None else anchors
            anchors[held, :2] += shift
            self._slid[held] = shift
            self.carried[held] = not toes.any()
        return anchors

    def glide(self, shift: np.ndarray) -> np.ndarray:
        """The anchors' ``shift`` (k, 3) [m] of this frame left to its carried heels, else 0.

        The body goes along with these at once (:meth:`.SupportFollower.shift`, not placed):
        a heel gliding on after it landed holds the body, which moves with it as it does with
        the truth's heel. Without this the support took each frame's glide for a disagreement
        and lagged the pelvis behind by it, catching up at ``lag_speed`` (0.3 m/s, slower than
        the glide), and the lag still left at the next take-off was lost: cmu-02-02-walk's
        landing heels held while their truth still glided, -11.5 mm (shape -12.6) of its 47 mm
        end error with perfect sensors, its flights a further -8.7 mm.
        A toe's carry (the tip sliding at push-off) stays lagged: moved with at once, it made
        cmu-02-02-walk's perfect drift 1.04 -> 1.54 % and jumped a joint by 4.3 deg.
        """
        return np.where(self.carried[:, None], shift, 0.0)

    def _velocities(self, held: np.ndarray, now: Mapping[str, np.ndarray],
                    before: Mapping[str, np.ndarray]) -> np.ndarray | None:
        """(n, 3) the ``held`` points' velocities over the frame [m/s]; None: one unknown.

        The mean of this frame's and the last frame's where both are known, else this frame's.
        """
        names = [self.names[i] for i in held]
        if not names or any(n not in now for n in names):
            return None
        v = np.array([np.asarray(now[n], dtype=float) for n in names])
        if all(n in before for n in names):
            v = 0.5 * (v + np.array([np.asarray(before[n], dtype=float) for n in names]))
        return v

    def _tip_slide(self, i: int, v_world_ball: np.ndarray, q: np.ndarray,
                   R_heading: np.ndarray | None) -> np.ndarray:
        """The slide (3,) [m/s] of toe point ``i`` whose ball moves at ``v_world_ball``.

        The hinge geometry is the solved pose ``q``'s (the solver's world, ``R_heading`` from
        the sensors' world, None for the same); velocities in and out are the sensors' world.
        """
        p_ball = self.model.segment_position(q, self._point_segments[i])
        p_tip = self.model.site_position(q, self.names[i])
        if R_heading is None:
            return floor_tip_slide(v_world_ball, p_ball, p_tip)
        return np.asarray(R_heading.T @ floor_tip_slide(R_heading @ v_world_ball, p_ball, p_tip))

    def relative_motion(self, state: ContactState, moving: np.ndarray | None
                        ) -> np.ndarray | None:
        """``moving`` (k,) (1 moves by its foot IMU, 0 not, NaN unknown) as the release sees it.

        A heel carried this frame moves with its anchor, not away from it: it holds the body as
        well as a still point. So a moving point of the other foot planted before it (the
        trailing toe of a walk, its tip lifting off at 0.5-1.5 m/s where the carry along the
        toe can no longer follow it) lets go once the landing heel is planted, even while that
        heel still glides (:func:`.contacts.release_contacts`: a moving point lets go while a
        point of the other foot that does not move stays planted). Only a heel planted after
        the moving points: at the start of a walk the heel that begins to lift (its IMU says it
        slides forward) must not take the body from the other foot's toe.
        """
        if moving is None or not any_true(self.carried):
            return moving
        others = state.active & (moving == 1.0) & ~self.carried
        if not any_true(others):
            return moving
        landed_later = self.carried & (state.age < state.age[others].max())
        return np.where(landed_later, 0.0, moving)
