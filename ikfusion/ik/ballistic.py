"""The pelvis in flight: a ballistic path from a take-off velocity the accelerometer keeps honest.

On the ground the pelvis velocity comes from the support (the body carried by its planted
feet), which is right in mid-stance but wrong in the last frames before a flight is confirmed:
the foot that already left the floor is still held there. The pelvis accelerometer knows
better. The velocity is therefore a complementary filter: the pelvis acceleration
``a_world_pelvis`` [m/s^2] integrated, pulled towards the support's velocity with time
constant ``tau`` [s] while the body stands, and left alone in the air. In flight the pelvis
target moves on ``p + v dt + a dt^2 / 2`` with the measured acceleration (about ``g`` in free
fall; exactly ``g`` when none is recorded).

Without an accelerometer the velocity is the solved one of the last frame (as before the
filter existed), and the flight is the parabola from it.

The accelerometer sits on the sacrum, a lever arm ``lever`` (about 10 cm behind and 5 cm above
the hip midpoint) away from the pelvis origin: as the pelvis turns, the sensor moves around the
origin. The filter therefore keeps the velocity of the *sensor* (what the accelerometer
measures: a walking pelvis's yaw of about 1 rad/s moves it 0.1 m/s sideways against the origin),
and the path of the origin takes off the sensor's motion around it each frame (``R_world_pelvis
lever`` from frame to frame). Without it a walk's push-off flew sideways at the sensor's swing
(6 cm/s across the track in cmu-02-02-walk, with perfect sensors).

The path never takes the body through the floor. Given the lowest pelvis height at which the
sensed pose keeps its contact points on or above the floor, a descending path that reaches it
*lands* (:attr:`BallisticRoot.landed`): from then on the pelvis is at that height, following
the sensed legs down onto the floor, until a planted point carries the body or the velocity
turns upward again. The velocity itself runs on through the landing (the deceleration the
accelerometer measures brings it to rest), so the next take-off starts from the right one.
Without that, a flight that the accelerometers end a few frames after the feet met the floor
(or a take-off velocity a little low) had the floor constraint met by bending the joints no
sensor watches, the toes, by tens of degrees, and the knees popped when the feet were planted.
Only a descending path lands: at a take-off the sensed feet, pointed with level toes, reach
through the floor where the real toes bend.

An outside estimate of where the body is (the UWB tags of the drift correction) moves the path
itself (:meth:`BallisticRoot.shift`), so there is one path that lands once: the correction
never flies the pelvis on a parabola of its own. A shift lowers the path at most onto the
landing height, never under it, whichever way the path flies: in a false flight of a body on
the floor (every point let go after the head's tag ran away) the path still rose with the
body's last velocity, so it had not landed, while the head's tag pulled it down; the pelvis
sank 16 cm under where the sensed pose meets the floor, the floor bent an elbow 12 deg away
from its sensors and the landing straightened it in one frame (issue #19).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .vec3 import ZERO, Vec3, floats

if TYPE_CHECKING:
    from ..model.human_model import HumanModel

GRAVITY = np.array([0.0, 0.0, -9.81])  #: [m/s^2] in the world frame (Z up)
_NO_SHIFT = np.zeros(3)  # :meth:`BallisticRoot.shift`'s start (read-only: shifts make new arrays)
_NO_SHIFT.setflags(write=False)
_ZERO_FLOATS = [0.0, 0.0, 0.0]  # no motion of the sensor around the origin [m] (never written)


class BallisticRoot:
    """Pelvis velocity across stance and flight; the ballistic pelvis target in flight.

    Args:
        tau: Time constant [s] with which the velocity follows the support while it stands
            (0: the support's velocity as is).
        lever: (3,) the accelerometer's position in the pelvis frame [m] (its offset from the
            pelvis origin); None: at the origin.
    """

    def __init__(self, tau: float, lever: np.ndarray | None = None) -> None:
        if tau < 0.0:
            raise ValueError(f"tau must be >= 0 s, got {tau}")
        self.tau = tau
        self.lever = None if lever is None else np.asarray(lever, dtype=float)
        self.reset()

    @property
    def velocity(self) -> np.ndarray:
        """(3,) [m/s] the filter's velocity (a new array; kept as floats)."""
        return np.array(self._velocity)

    @velocity.setter
    def velocity(self, value: np.ndarray) -> None:
        self._velocity = floats(value)

    def reset(self) -> None:
        """At rest, nothing measured."""
        self._velocity = ZERO  # :attr:`velocity`'s floats
        self.position: np.ndarray | None = None  # on the path in flight, None on the ground
        #: the path came down onto the floor and follows the feet there
        self.landed = False
        self._shift = _NO_SHIFT  # moves the next target (and the path after it) [m]
        self._lever_world: np.ndarray | None = None  # the last frame's R_world_pelvis lever
        self._lever_floats: list[float] | None = None  # ... as floats

    def shift(self, delta: np.ndarray) -> None:
        """Move the path by ``delta`` (3,) [m] from the next frame of flight on.

        Given between two frames (after :meth:`update`), it moves the next :meth:`target` and
        so the rest of the flight; a shift the next frame does not fly on (a planted point
        carries the body, a planner's target) is dropped. The caller bounds it per frame. The
        landing height still bounds the moved path, and a downward shift never takes the
        path under it (nor lower than the path flies by itself when it is under already).
        """
        self._shift = self._shift + np.asarray(delta, dtype=float)

    def target(self, p_last: np.ndarray, dt: float, a_world: np.ndarray | None,
               lowest_z: float | None = None,
               R_world_pelvis: np.ndarray | None = None) -> np.ndarray:
        """The pelvis position (3,) [m] ``dt`` [s] further on the ballistic path.

        The path starts at ``p_last`` (the solved pelvis) at the take-off and then runs on by
        itself, so a solve that lags its target does not slow the flight down. A pending
        :meth:`shift` moves it before the landing height is applied.

        Args:
            p_last: (3,) the solved pelvis of the last frame [m].
            dt: Time since the last frame [s].
            a_world: (3,) the pelvis acceleration in the world frame [m/s^2] or None.
            lowest_z: The lowest pelvis height [m] at which the body's contact points stay
                on or above the floor (None: no floor). A descending path lands there and
                stays at that height while it does not rise (see the module docstring).
            R_world_pelvis: (3, 3) this frame's pelvis orientation (the accelerometer's lever
                arm); None: the sensor's motion is the origin's.
        """
        a = GRAVITY if a_world is None or not _finite(a_world) else a_world
        start = p_last if self.position is None else self.position
        around = self._lever_step(R_world_pelvis)  # the sensor's motion around the origin
        free = np.asarray(start + self.velocity * dt + 0.5 * a * dt * dt - around)
        self.position = free + self._shift
        if lowest_z is not None and self._shift[2] < 0.0:
            # a shift may lower the path onto the landing height, never under it
            self.position[2] = max(float(self.position[2]), min(float(free[2]), lowest_z))
        self._shift = _NO_SHIFT
        descending = bool(self._velocity[2] * dt <= around[2])  # the origin's velocity
        self.landed = (lowest_z is not None and descending
                       and (self.landed or bool(self.position[2] < lowest_z)))
        if self.landed and lowest_z is not None:
            self.position[2] = lowest_z
        return self.position.copy()

    def update(self, v_solved: np.ndarray, dt: float, a_world: np.ndarray | None,
               supported: bool, R_world_pelvis: np.ndarray | None = None) -> None:
        """After a frame: fold in its solved pelvis velocity and its acceleration.

        Args:
            v_solved: (3,) the pelvis velocity of the solve [m/s] (the finite difference).
            dt: Time since the last frame [s].
            a_world: (3,) the pelvis acceleration in the world frame [m/s^2], None if not
                recorded (then the velocity on the ground is ``v_solved``, in flight gravity
                alone changes it).
            supported: Whether a planted point carried the body this frame.
            R_world_pelvis: (3, 3) the frame's pelvis orientation, as given to :meth:`target`.
        """
        self._shift = _NO_SHIFT  # a shift is for the frame after the one it was given in
        lever_now = self._lever_world_of(R_world_pelvis)
        now = None if lever_now is None else lever_now.tolist()
        was, self._lever_world, self._lever_floats = self._lever_floats, lever_now, now
        # the sensor's motion around the origin [m], in floats (NumPy's differences)
        around = _ZERO_FLOATS if now is None or was is None else [
            now[0] - was[0], now[1] - was[1], now[2] - was[2]]
        a = None if a_world is None else _floats(a_world)
        measured = a is not None and all(map(math.isfinite, a))
        if not supported:  # in flight: the path's own velocity
            a_flight = a_world if measured and a_world is not None else GRAVITY
            self.velocity = self.velocity + a_flight * max(dt, 0.0)
            return
        self.position = None
        self.landed = False
        if not measured or a is None or dt <= 0.0:
            self.velocity = np.asarray(v_solved, dtype=float) + (
                np.array(around) / dt if dt > 0 else 0.0)
            return
        self._velocity = _filtered(self._velocity, np.asarray(v_solved, dtype=float).tolist(),
                                   around, a, dt, self.tau)

    def _lever_world_of(self, R_world_pelvis: np.ndarray | None) -> np.ndarray | None:
        """(3,) the accelerometer's offset from the pelvis origin in the world [m], or None."""
        if self.lever is None or R_world_pelvis is None:
            return None
        return np.asarray(R_world_pelvis @ self.lever)

    def _lever_step(self, R_world_pelvis: np.ndarray | None) -> np.ndarray:
        """(3,) how far [m] the accelerometer moved around the pelvis origin since the last frame.

        Zero without a lever arm or an orientation for this frame or the last one.
        """
        lever_now = self._lever_world_of(R_world_pelvis)
        if lever_now is None or self._lever_world is None:
            return np.zeros(3)
        return np.asarray(lever_now - self._lever_world)


def _filtered(v: Vec3, v_solved: list[float], around: list[float], a: list[float],
              dt: float, tau: float) -> Vec3:
    """The standing filter's velocity [m/s], per axis with floats (NumPy's numbers on (3,)).

    ``v``: the kept velocity, ``v_solved``: the solve's finite difference [m/s], ``around``:
    the sensor's motion around the origin [m], ``a``: the acceleration [m/s^2], over ``dt`` > 0
    [s] with time constant ``tau`` [s]: ``v + a dt`` pulled towards ``v_solved + around / dt +
    a dt / 2`` (the finite difference is the velocity half a frame back, at the origin).
    """
    gain = 1.0 if tau == 0.0 else min(1.0, dt / tau)
    (vx, vy, vz), (sx, sy, sz), (rx, ry, rz), (ax, ay, az) = v, v_solved, around, a
    # per axis: predicted = v + a dt, v_now = v_solved + around / dt + 0.5 a dt
    px, py, pz = vx + ax * dt, vy + ay * dt, vz + az * dt
    return (px + gain * (sx + rx / dt + 0.5 * ax * dt - px),
            py + gain * (sy + ry / dt + 0.5 * ay * dt - py),
            pz + gain * (sz + rz / dt + 0.5 * az * dt - pz))


def sensor_lever(model: HumanModel, segment: str = "Pelvis") -> np.ndarray | None:
    """(3,) the sensor site of ``segment`` in its frame [m] (the lever arm), None without one."""
    if segment not in model.sites_of_kind("sensor"):
        return None
    q = model.neutral()
    R = model.segment_rotation(q, segment)
    return np.asarray(R.T @ (model.site_position(q, segment) - model.segment_position(q, segment)))


_FLOAT = np.dtype(float)


def _floats(a: np.ndarray) -> list[float]:
    """``np.asarray(a, dtype=float).ravel().tolist()`` (a (3,) float array's own list at once)."""
    if type(a) is np.ndarray and a.dtype == _FLOAT and a.ndim == 1:
        return a.tolist()  # type: ignore[no-any-return]
    return np.asarray(a, dtype=float).ravel().tolist()  # type: ignore[no-any-return]


def _finite(a: np.ndarray) -> bool:
    """Every entry of ``a`` finite (``np.all(np.isfinite(a))`` without NumPy's overhead)."""
    return all(map(math.isfinite, _floats(a)))
