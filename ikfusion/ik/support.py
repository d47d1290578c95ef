"""Smooth hand-overs of the body between its feet, and swing feet placed by the correction.

Each frame the solver starts from the sensed pose translated so that the planted points of the
*reference* foot (the one planted longest) sit on their anchors on average: the *support
offset*. When the body is handed to the other foot (a toe lets go), the two feet rarely agree
exactly: inertial drift between steps, or a foot placed by the ``no-slide`` correction where the
sensed leg would not put it. The support offset then jumps, and a body that followed it would
jump with it.

:class:`SupportFollower` keeps the pelvis continuous instead: the jump becomes a *lag* (3,) [m]
between the pelvis and its warm-start position, which shrinks at a bounded speed while the
planted legs take it up through their joints. The pelvis follows ``warm start + lag + lean``
as a soft position task.

For the ``no-slide`` correction it also leads swing feet and leans the pelvis: when a foot lifts
off, the correction still to make (less what the lag will still bring) is latched for it, at
most ``max_step``, and the foot is led toward it during the swing (a soft position task on its
heels, relative to the pelvis), starting from where its heel left the floor; it lands where the
corrected body wants it, with no jump at touch-down (in height, see :mod:`.swing_lead`).
Meanwhile the pelvis leans toward the correction by at most ``lean_max``; the lean passes into
the lag when the body is handed to a foot that was placed leaning.
"""

from __future__ import annotations

import numpy as np

from ..model.topology import FootLayout
from . import vec3
from .fast_math import mean_rows
from .point_bits import indices, point_bits
from .support_motion import KeptClip, leaned, shrunk_lag, swing_toward
from .swing_lead import LedBase, band_share, lead_targets
from .vec3 import ZERO, Vec3, floats


class SupportFollower:
    """Pelvis lag across hand-overs and swing-foot offsets (see the module docstring).

    Args:
        layout: The contact points' feet (two; :meth:`BodyTopology.foot_layout`).
        lag_speed: The lag shrinks at this speed [m/s].
        lag_max: ... and is never longer than this [m] (larger disagreements are jumped over).
        swing_speed: A swing foot moves toward its offset at this speed [m/s].
        lean_max: The pelvis leans toward the correction at most this far [m] ...
        lean_speed: ... at this speed [m/s].
        confirm: A touch-down counts once the foot stayed planted this long [s].
        floor_z: Height of the floor [m] (world z): a swing foot whose sensed points sink under
            it is led horizontally only.
    """

    def __init__(self, layout: FootLayout, lag_speed: float, lag_max: float,
                 swing_speed: float, lean_max: float, lean_speed: float,
                 confirm: float, floor_z: float = 0.0) -> None:
        self.floor_z, self.swing_speed = floor_z, swing_speed
        self.lag_speed, self.lag_max = lag_speed, lag_max
        self.lean_max, self.lean_speed = lean_max, lean_speed
        self.confirm, k = confirm, len(layout.on_foot)
        feet = [np.asarray(f, dtype=bool) for f in layout.feet]
        self._feet = tuple(feet + [np.zeros(k, dtype=bool)] * (2 - len(feet)))
        # groups as bits of ints (:mod:`.point_bits`): bit f of a groups' mask is ``_feet[f]``
        self._bits = point_bits(layout)
        self._group_points = [self._bits.of(f) for f in self._feet]  # each group's points
        self._all_groups = (1 << len(self._feet)) - 1
        self._planted_of: dict[int, int] = {}  # _planted's, per pattern of points
        # only feet proper (bits of groups) are led through a swing; knees and palms land where
        # the body puts them
        self._steps = sum(1 << i for i, f in enumerate(self._feet) if (f & layout.stepping).any())
        self._led = np.asarray(layout.on_foot, dtype=bool)  # led by its heels, not unsensed toes
        self._buffer = np.zeros(3)  # for :mod:`.vec3`'s norms
        self.reset()

    @property
    def lag(self) -> np.ndarray:
        """The pelvis's lag (3,) [m] (a new array; kept as floats, :mod:`.vec3`)."""
        return np.array(self._lag)

    @lag.setter
    def lag(self, value: np.ndarray) -> None:
        self._lag = floats(value)

    @property
    def lean(self) -> np.ndarray:
        """Its lean toward the correction (3,) [m] (a new array)."""
        return np.array(self._lean)

    @property
    def swing(self) -> np.ndarray:
        """Each foot's swing offset (n, 3) [m] (a new array)."""
        return np.array(self._swing)

    @property
    def landed(self) -> np.ndarray:
        """Swing offsets of the feet that touched down this frame, summed (3,) [m]."""
        return np.array(self._landed)

    def reset(self) -> None:
        """Forget the support, the lag and every offset."""
        # the 3-vectors [m] as tuples of floats (:mod:`.vec3`); :attr:`lag` ... give arrays
        self._support: tuple[int, list[list[float]]] | None = None  # (points (bits), anchors)
        self._lag = self._lean = self._step = self._off_target = self._landed = ZERO
        self._allowance = self._max_step = 0.0
        n = len(self._feet)
        self._swinging, self._planted_for = [False] * n, [0.0] * n
        self._height_trust = [1.0] * n  # how far a swing heel is held at its sensed height
        self._goal = [ZERO] * n
        self._has_goal = [False] * n  # any(self._goal[f]), kept with it
        self._swinging_bits = self._goal_bits = 0  # bit f: ``_swinging[f]``, ``_has_goal[f]``
        self._swing, self._landed_swing = [ZERO] * n, [ZERO] * n
        self._led_base = LedBase(len(self._led))  # where the contact points were led
        self._target: Vec3 | None = None
        self._wanted = KeptClip()  # where the lean goes (the same most frames)
        self._placed_by = np.zeros((n, 3))  # how far each foot's anchors were moved on purpose
        self._reference_feet = self._all_groups  # the groups (bits) the body stands on

    # ------------------------------------------------------------------ corrections
    def set_step(self, offset: np.ndarray, max_step: float) -> None:
        """The horizontal correction (3,) [m] the body still needs, by steps of ``max_step`` [m].

        A foot that lifts off is led by this correction less what the pelvis will still move
        (:attr:`pending`), at most ``max_step``.
        """
        self._step = (float(offset[0]), float(offset[1]), 0.0)
        self._max_step = float(max_step)

    def shift(self, delta: np.ndarray) -> None:
        """The anchors moved by ``delta`` (3,) [m] on purpose: the body follows them at once."""
        self._placed_by += delta
        self.carry_held(delta)

    def carry_held(self, delta: np.ndarray) -> None:
        """Held anchors moved by ``delta`` (3,)/(k, 3) [m], not placed (a glide): the body goes."""
        if self._support is not None:
            self._support = (self._support[0], (np.array(self._support[1]) + delta).tolist())

    @property
    def displacement(self) -> np.ndarray:
        """How far the corrections have moved the pelvis from the inertial body (3,) [m].

        The intended placement of the foot the body stands on, plus the lag and the lean.
        """
        return self._reference_placed() + self._lag + self._lean

    def _reference_placed(self) -> np.ndarray:
        """How far the groups the body stands on were placed on purpose, on average (3,) [m]."""
        return self._placed_by[list(indices(self._reference_feet))].mean(axis=0)

    @property
    def placed(self) -> bool:
        """Does the lag hold a foot the correction placed on purpose (not just drift)?"""
        return self._allowance > self.lag_max

    @property
    def placed_share(self) -> float:
        """How much of the lag is a placed foot, 0 (drift only) to 1 (``lag_max`` or more).

        The pelvis is held to its target the more firmly the more it is: a weight that
        switched at once would let the pelvis snap when the placed part has been caught up.
        """
        if self.lag_max <= 0:
            return 1.0 if self.placed else 0.0
        return min(max((self._allowance - self.lag_max) / self.lag_max, 0.0), 1.0)

    @property
    def pending(self) -> Vec3:
        """How far the lag will still move the pelvis (3,) [m] (horizontal)."""
        return (-self._lag[0], -self._lag[1], 0.0)

    def moves_pelvis(self) -> bool:
        """Whether the lag or the lean is not zero (the pelvis is held to its target)."""
        return any(self._lag) or any(self._lean)

    def led_points(self, p_warm: np.ndarray) -> np.ndarray:
        """Points (c, 3) [m] moved by the lag and the lean: ``p_warm + lag + lean``."""
        return p_warm + self._lag + self._lean

    # ------------------------------------------------------------------ per frame
    def follow(self, active: np.ndarray | int, anchors: np.ndarray | list[list[float]],
               p_sensed: np.ndarray, dt: float) -> np.ndarray:
        """The support offset (3,) [m] of this frame; updates the lag and the swing feet.

        Args:
            active: (k,) planted points (at least one), or their bits (:mod:`.point_bits`).
            anchors: (k, 3) their anchors [m] (or their rows as lists of floats, not changed).
            p_sensed: (k, 3) contact points of this frame's sensed pose (any translation) [m].
            dt: Time since the last frame [s].
        """
        on = active if isinstance(active, int) else self._bits.of(active)
        planted = self._planted_of.get(on) or self._planted(on)
        self._settle_landings(planted, dt)
        reference = self._reference(on, planted)
        # rows of floats (:mod:`.vec3`)
        rows = anchors if isinstance(anchors, list) else anchors.tolist()
        sensed = p_sensed.tolist()
        offset = vec3.mean_rows(rows, indices(reference), sensed)
        moved = ZERO  # how far the pelvis target moves to where the pelvis was solved
        lag, lean, buffer = self._lag, self._lean, self._buffer
        if self._support is not None:
            was, held = self._support
            if was:  # the last frame's support now, less this frame's (equal rows: one mean)
                same = was == reference and (held is rows or held == rows)  # (rows kept)
                then = offset if same else vec3.mean_rows(held, indices(was), sensed)
                lag = vec3.add(lag, vec3.sub(then, offset))
            if not was & reference:
                # the body is handed to a foot that was placed leaning: the lean is in it now;
                # and the pelvis goes on from where it was solved, not from its soft target
                lag = vec3.add(lag, vec3.add(lean, self._off_target))
                moved, lean = self._off_target, ZERO
                # what the correction placed on purpose is caught up with, never jumped over
                self._allowance = self.lag_max + vec3.norm(
                    self._landed_swing[self._foot_of(reference)], buffer)
        self._allowance = allowance = max(self.lag_max, self._allowance - self.lag_speed * dt)
        self._lag = lag = shrunk_lag(lag, self.lag_speed * dt, allowance, buffer)
        self._lean = leaned(lean, self._step, lag, self._wanted, self.lean_max,
                            self.lean_speed * dt, buffer)
        self._support = (reference, rows)
        self._reference_feet = self._planted_of.get(reference) or self._planted(reference)
        if self._all_groups & ~planted:  # (the usual frame: every foot planted, none swings)
            self._update_swing(planted, dt, moved)
        return np.array(offset)

    def _foot_of(self, points: int) -> int:
        """The foot (index in the layout's feet) of the first of ``points`` (bits)."""
        return next((f for f, g in enumerate(self._group_points) if points & g), 0)

    def _planted(self, points: int) -> int:
        """The groups (foot, knee, palm; bits) with one of ``points`` (bits)."""
        groups = self._planted_of.get(points)
        if groups is None:
            groups = self._planted_of[points] = sum(
                1 << f for f, g in enumerate(self._group_points) if points & g)
        return groups

    def _reference(self, active: int, planted: int) -> int:
        """The planted points of the foot planted longest (both feet when they landed together).

        While both feet are planted the body stays on the foot it stood on: a foot that just
        landed, led away from where the sensed legs put it, takes the body over only when the
        other foot lets go, so the leg that leaves the floor carries no strain that would snap.
        """
        if planted and not planted & (planted - 1):  # the usual frame: one foot planted
            return self._group_points[planted.bit_length() - 1] & active
        age, on, groups = self._planted_for, indices(planted), self._group_points
        longest = max([age[f] for f in on])
        return sum([groups[f] for f in on if age[f] == longest]) & active

    def lose_support(self) -> None:
        """No point is planted (flight): the ballistic path takes over; nothing lags."""
        self._support = None
        self._lag = ZERO

    def _settle_landings(self, planted: int, dt: float) -> None:
        """Groups ``planted`` (bits) that touched down stay where they were led (``landed``)."""
        self._landed = ZERO
        swinging, age, swing_of = self._swinging, self._planted_for, self._swing
        for f in indices(planted):
            if swinging[f]:
                swinging[f] = False
                self._landed_swing[f] = swing = swing_of[f]
                age[f] = 0.0
                self._landed = vec3.add(self._landed, swing)
                # led from the pelvis, which stood where the reference foot and lag put it
                self._placed_by[f] = self.displacement + swing
            else:
                age[f] += dt
            swing_of[f] = ZERO
        self._swinging_bits &= ~planted

    def _update_swing(self, planted: int, dt: float, moved: Vec3) -> None:
        """Latch the offset of feet that lifted off and move swinging feet.

        Swing feet are led relative to the pelvis target: when it ``moved`` (3,) [m] to
        where the pelvis was solved, their offsets take that back, so they are not pulled along.

        A foot that lets go again within ``confirm`` seconds of touching down (a heel strike
        its gyroscope did not confirm) resumes its swing toward the same goal, from where its
        heel is (held while the body moved on, it is no longer where it was led: a swing
        resumed there jumped the heel by centimetres), and its landing is not counted.
        """
        lifted, swinging, swing_of = self._all_groups & ~planted, self._swinging, self._swing
        for f in indices(lifted & ~self._steps & ~self._swinging_bits):
            swinging[f] = True  # lifted, never led: lands with no swing offset
        for f in indices(lifted & self._steps):
            if not swinging[f]:
                self._lift_off(f)
            swing_of[f] = swing_toward(swing_of[f], self._goal[f], self.swing_speed * dt, moved,
                                       self._buffer)
        self._swinging_bits |= lifted

    def _lift_off(self, f: int) -> None:
        """Group ``f`` (a foot) lifts off: latch its goal, its swing starts where its heel is."""
        self._swinging[f] = True
        if self._planted_for[f] < self.confirm and any(self._landed_swing[f]):
            self._landed = vec3.sub(self._landed, self._landed_swing[f])  # not counted
        else:  # (a resumed swing keeps its goal)
            self._goal[f] = vec3.clip_norm(vec3.sub(self._step, self.pending),
                                           self._max_step, self._buffer)
            self._has_goal[f] = has_goal = any(self._goal[f])
            self._goal_bits = self._goal_bits & ~(1 << f) | has_goal << f
        # the heel leaves the floor where it is, not where the sensed leg puts it (nor
        # where it was led before a short touch-down: the body moved under it since)
        swing = self._swing[f] = tuple(  # type: ignore[assignment]
            mean_rows(self._led_base.deviation()[self._feet[f] & self._led]).tolist())
        # a sensed leg that disagreed with the floor's height does not set the heel's
        self._height_trust[f] = band_share(-abs(swing[2]))
        self._landed_swing[f] = ZERO

    def pelvis_target(self, p_warm: np.ndarray) -> Vec3:
        """Where the pelvis should be (3,) [m], its warm start ``p_warm`` plus lag and lean."""
        (x, y, z), lag, lean = p_warm.tolist(), self._lag, self._lean
        self._target = (x + lag[0] + lean[0], y + lag[1] + lean[1], z + lag[2] + lean[2])
        return self._target

    def record(self, p_solved: np.ndarray, p_pelvis: np.ndarray) -> None:
        """After solving: how far the contact points and the pelvis are from where they were led.

        Args:
            p_solved: (k, 3) solved contact points [m].
            p_pelvis: (3,) solved pelvis position [m].
        """
        self._led_base.record(p_solved)
        x, y, z = p_pelvis.tolist()
        self._off_target = ZERO if self._target is None else vec3.sub((x, y, z), self._target)
        self._target = None

    def placed_offsets(self, active: np.ndarray | int) -> np.ndarray | None:
        """(k, 3) [m]: how far each planted point was placed from where the sensed legs put it.

        While two feet (or knees, palms) are planted (``active``: (k,) or bits), the youngest was
        led by its swing offset: they disagree by that much on purpose, not drift. None while
        fewer are planted.
        """
        planted = self._planted(active if isinstance(active, int) else self._bits.of(active))
        if planted.bit_count() < 2:
            return None
        out = np.zeros((self._bits.k, 3))
        # a foot that touched down since the last frame swings until the body follows: the youngest
        age = [-1.0 if self._swinging[f] else t for f, t in enumerate(self._planted_for)]
        young = min(indices(planted), key=age.__getitem__)  # the first of the youngest
        fresh = self._swinging[young]
        if not self._has_goal[young]:  # not led: only its swing (a resumed one)
            out[self._feet[young]] = self._swing[young] if fresh else self._landed_swing[young]
            return out
        # led from the pelvis (lag, lean) plus its swing: as :meth:`_settle_landings` records
        placed = self.displacement + self._swing[young] if fresh else self._placed_by[young]
        out[self._feet[young]] = placed - self._reference_placed()
        return out

    def leads(self) -> bool:
        """Whether a swinging foot is led now (:meth:`swing_targets` gives it information)."""
        return bool(self._swinging_bits & self._goal_bits)

    def keep_base(self, p_sensed: np.ndarray, offset: np.ndarray) -> None:
        """Keep the contact points (k, 3) [m] of the warm start for :meth:`record` (no swing).

        ``p_sensed + offset`` (3,) and this frame's lag and lean, summed at a lift-off only.
        """
        self._led_base.keep(p_sensed, self._lag, self._lean, offset)

    def swing_targets(self, p_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Targets (k, 3) [m] and information (k, 3, 3) of the heels of swing feet led now.

        ``p_points``: (k, 3) contact points of the warm start (the sensed pose on the support,
        plus the lag) [m]. See :func:`.swing_lead.lead_targets`.
        """
        self._led_base.keep(p_points.copy())
        led = [(points, self._swing[f], self._height_trust[f])
               for f, points in enumerate(self._feet) if self._swinging[f] and self._has_goal[f]]
        return lead_targets(p_points, led, self._led, self.floor_z)
