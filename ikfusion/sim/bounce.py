"""Procedural bouncing gaits with flight: one-leg hops, skipping and two-foot jumps.

A bouncing gait is a sequence of *bounces*: a stance on one foot or on both, then a flight in
which the body is a projectile. The plan is physically consistent where it matters for the
sensors and the contacts:

* in flight the pelvis follows a parabola: constant horizontal velocity (the chord between
  take-off and landing) and vertical acceleration -9.81 m/s^2, so every accelerometer of the
  trunk reads free fall (|specific force| near 0);
* in stance the pelvis joins landing and take-off smoothly (position and velocity continuous;
  a cubic dip that absorbs the landing and launches the next flight), the stance feet are flat
  on their footprints and their heels and toes are the generator's contact phases;
* the feet that fly swing from footprint to footprint with clearance (and rise with the pelvis
  in flight, so a leg is never stretched beyond reach); a one-leg hop holds the free foot up
  behind, knee bent.

Bounce schedules: ``"hop"`` right foot only, ``"jump"`` both feet, ``"skip"`` right, right,
left, left, ... (step-hop on each leg). After the standing N-pose the free foot lifts, and a
countermovement launches the first flight. Positions in metres, times in seconds, world Z up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..ik.frame import Frame
from ..model.human_model import HumanModel
from ..rotations import axis_rotation
from .gait import _UPPER_BODY, SIDES, GaitParameters, GaitPlanner, _smoothstep, feet_frame

G = 9.81  #: [m/s^2]
#: Time the free foot takes to lift off after the standing N-pose [s].
_LIFT = 0.5
#: Length of the countermovement that launches the first flight [s].
_COUNTER = 0.5
#: Hip, knee and ankle flexion of a hop's free leg [deg].
_HELD_DEG = (20.0, 80.0, 20.0)


@dataclass(frozen=True)
class _Stance:
    """A foot flat on the floor from ``start`` to ``end`` [s], ankle at ``p`` [m], ``yaw`` [rad]."""

    start: float
    end: float
    p: np.ndarray
    yaw: float


class BouncePlanner(GaitPlanner):
    """Plans a bouncing gait (``parameters.bounce``); see the module docstring.

    Args:
        model: The human model.
        parameters: The gait: ``bounce``, ``contact_time``, ``flight_time``, ``speed``,
            ``path`` and its radius, ``clearance``, ``stand``, ``duration``.
    """

    def __init__(self, model: HumanModel, parameters: GaitParameters) -> None:
        super().__init__(model, parameters)
        p = parameters
        if p.bounce not in ("hop", "skip", "jump"):
            raise ValueError(f"unknown bounce {p.bounce!r}; use hop, skip or jump")
        period = p.contact_time + p.flight_time
        first = p.stand + _LIFT + _COUNTER  # first take-off
        n = int(np.ceil((p.duration - first) / period)) + 5  # feet swing to the next beyond
        #: take-off times b_j and landing times a_j (a_0: the standing start)
        self.take_off = first + period * np.arange(n)
        self.landing = np.concatenate([[0.0], self.take_off[:-1] + p.flight_time])
        self.z_launch = self.pelvis_height - 0.02  # pelvis height at take-off and landing
        self.vz = 0.5 * G * p.flight_time  # vertical speed at take-off and landing
        self._xy = [self.path.at(self.distance(t))[0] for t in self.take_off]
        self._xy_land = [self.path.at(self.distance(t))[0] for t in self.landing]
        self.stances = {side: self._stances(side, n) for side in SIDES}
        q0 = model.neutral()
        self._lengths = {side: (
            float(np.linalg.norm(model.segment_position(q0, f"{side}LowerLeg")
                                 - model.segment_position(q0, f"{side}UpperLeg"))),
            float(np.linalg.norm(model.segment_position(q0, f"{side}Foot")
                                 - model.segment_position(q0, f"{side}LowerLeg"))))
            for side in SIDES}

    def distance(self, t: float) -> float:
        """Arc length [m] of the path at ``t`` [s].

        The speed ramps up from the first take-off: the body launches from where it stands.
        """
        return super().distance(t - (self.take_off[0] - self.p.stand))

    def _tau(self, t: float) -> float:
        """Time since the first take-off [s]: the arms and trunk start moving then."""
        return t - float(self.take_off[0])

    # ------------------------------------------------------------------ schedule
    def _on(self, side: str, j: int) -> bool:
        """Does ``side`` stand in bounce ``j``?"""
        kind = self.p.bounce
        if kind == "jump":
            return True
        if kind == "hop":
            return side == "Right"
        return (side == "Right") == ((j // 2) % 2 == 0)

    def _stances(self, side: str, n: int) -> list[_Stance]:
        out = []
        for j in range(n):
            if j == 0:  # the standing start; a foot not in the first bounce lifts off early
                end = self.take_off[0] if self._on(side, 0) else self.p.stand + _LIFT
                p_flat, yaw = self.footprint(side, -1)
                out.append(_Stance(0.0, float(end), p_flat, yaw))
            elif self._on(side, j):
                mid = 0.5 * (self.landing[j] + self.take_off[j])
                p_flat, yaw = self.beside_path(side, self.distance(mid))
                out.append(_Stance(float(self.landing[j]), float(self.take_off[j]), p_flat,
                                   float(yaw)))
        return out

    def bounce_at(self, t: float) -> tuple[int, bool]:
        """(bounce index, in flight) at time ``t``: flight ``j`` follows stance ``j``."""
        j = int(np.searchsorted(self.take_off, t, side="right"))  # take-offs passed
        if j == 0:
            return 0, False
        if t < self.landing[j]:
            return j - 1, True
        return j, False

    # ------------------------------------------------------------------ pelvis
    def pelvis(self, t: float) -> np.ndarray:
        """Pelvis origin ``p_world_pelvis`` (3,) [m] at ``t`` [s]."""
        p = self.p
        j, flying = self.bounce_at(t)
        if flying:
            s = t - self.take_off[j]
            xy = self._xy[j] + self._chord_velocity(j) * s
            z = self.z_launch + self.vz * s - 0.5 * G * s * s
            return np.array([xy[0], xy[1], z])
        b = self.take_off[j]
        if j == 0:
            a = p.stand
            if t <= a:
                xy = self._xy_land[0]
                return np.array([xy[0], xy[1], self.pelvis_height])
            u0 = np.zeros(2)
            xy = _hermite(t, a, b, self._xy_land[0], u0, self._xy[0], self._chord_velocity(0))
            a_z = b - _COUNTER
            z = (self.pelvis_height if t <= a_z else
                 _hermite(t, a_z, b, self.pelvis_height, 0.0, self.z_launch, self.vz))
            return np.array([xy[0], xy[1], float(z)])
        a = self.landing[j]
        xy = _hermite(t, a, b, self._xy_land[j], self._chord_velocity(j - 1), self._xy[j],
                      self._chord_velocity(j))
        z = _hermite(t, a, b, self.z_launch, -self.vz, self.z_launch, self.vz)
        return np.array([xy[0], xy[1], float(z)])

    def _chord_velocity(self, j: int) -> np.ndarray:
        """Horizontal pelvis velocity (2,) [m/s] in flight ``j``."""
        return np.asarray((self._xy_land[j + 1] - self._xy[j]) / self.p.flight_time)

    # ------------------------------------------------------------------ feet
    def foot(self, side: str, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, bool]:
        """``(R_world_foot, p_world_ankle, R_world_toe, heel_contact, toe_contact)``."""
        stances = self.stances[side]
        k = next((i for i, s in enumerate(stances) if s.start <= t < s.end), None)
        if k is not None:
            s = stances[k]
            R = axis_rotation("z", s.yaw)
            return R, s.p.copy(), R, True, True
        before = [s for s in stances if s.end <= t]
        after = [s for s in stances if s.start > t]
        last = before[-1]
        # in flight the swing foot rises with the pelvis (z_launch at take-off and landing)
        rise = max(0.0, float(self.pelvis(t)[2]) - self.z_launch) if self.bounce_at(t)[1] \
            else 0.0
        if len(stances) == 1:  # a hop's free foot: lifted behind, knee bent
            return self._held(side, t, last)
        nxt = after[0]
        f = (t - last.end) / (nxt.start - last.end)
        w = float(_smoothstep(f))
        p = (1.0 - w) * last.p + w * nxt.p
        p[2] += rise + 2.0 * self.p.clearance * np.sin(np.pi * f) ** 2
        yaw = last.yaw + w * np.angle(np.exp(1j * (nxt.yaw - last.yaw)))
        R = axis_rotation("z", yaw) @ axis_rotation("y", np.radians(15.0) * np.sin(np.pi * f))
        return R, p, R, False, False

    def _held_side(self, t: float) -> tuple[str, float] | None:
        """The side of a hop's free foot and how far it is lifted (0 to 1), None if none."""
        for side in SIDES:
            stances = self.stances[side]
            if len(stances) == 1 and stances[0].end <= t:
                return side, float(_smoothstep((t - stances[0].end) / _LIFT))
        return None

    def _held(self, side: str, t: float, last: _Stance) -> tuple[
            np.ndarray, np.ndarray, np.ndarray, bool, bool]:
        """The free foot of a hop: from its footprint up behind the body within ``_LIFT``.

        The leg's joints flex by ``w _HELD_DEG`` as ``w`` goes from 0 to 1; what the pelvis
        moved since lift-off fades out meanwhile (the foot starts on its footprint).
        """
        w = float(_smoothstep((t - last.end) / _LIFT))
        _, heading = self.path.at(self.distance(t))
        R_body = axis_rotation("z", heading + np.radians(self.p.facing_deg))
        offset, pitch = self._held_pose(side, w)
        straight, _ = self._held_pose(side, 0.0)
        pelvis = self.pelvis(t)
        p = pelvis + R_body @ offset + (1.0 - w) * (last.p - pelvis - R_body @ straight)
        R = R_body @ axis_rotation("y", pitch)
        return R, p, R, False, False

    def _held_pose(self, side: str, w: float) -> tuple[np.ndarray, float]:
        """Ankle offset from the pelvis (3,) [m] in the body frame, and foot pitch [rad].

        With the hip, knee and ankle flexed by ``w _HELD_DEG``.
        """
        q0 = self.model.neutral()
        hip, knee, ankle = (w * a for a in _HELD_DEG)
        q = self.model.configuration({f"j{side}Hip_flex": hip, f"j{side}Knee_flex": knee,
                                      f"j{side}Ankle_flex": ankle}, p_world_pelvis=q0[:3])
        R = self.model.segment_rotation(q, f"{side}Foot")
        offset = self.model.segment_position(q, f"{side}Foot") - q[:3]
        return offset, float(np.arctan2(R[0, 2], R[0, 0]))

    def _leg(self, side: str, hip: np.ndarray, ankle: np.ndarray,
             R_world_pelvis: np.ndarray) -> dict[str, np.ndarray]:
        """Thigh and shank orientations reaching from ``hip`` to ``ankle`` [m], knee forward.

        A planar two-link solution in the plane of the hip-ankle line and the pelvis forward
        axis; it only guides the solve (the contact points and feet are what is held).
        """
        thigh, shank = self._lengths[side]
        d = ankle - hip
        reach = float(np.linalg.norm(d))
        down = d / reach
        lateral = np.cross(R_world_pelvis[:, 0], down)  # points to the body's left
        lateral /= np.linalg.norm(lateral)
        forward = np.cross(down, lateral)
        reach = min(reach, 0.995 * (thigh + shank))  # knees soft, away from the singularity
        # the angle at the hip between the hip-ankle line and the thigh (law of cosines)
        cos_hip = (thigh**2 + reach**2 - shank**2) / (2.0 * thigh * reach)
        a = float(np.arccos(np.clip(cos_hip, -1.0, 1.0)))
        knee = hip + thigh * (np.cos(a) * down + np.sin(a) * forward)
        out = {}
        for segment, top, bottom in ((f"{side}UpperLeg", hip, knee),
                                     (f"{side}LowerLeg", knee, hip + d)):
            z = (top - bottom) / np.linalg.norm(top - bottom)
            x = np.cross(lateral, z)
            out[segment] = np.column_stack([x / np.linalg.norm(x), np.cross(z, x), z])
        return out

    # ------------------------------------------------------------------ targets
    def frame(self, t: float) -> Frame:
        """All targets and contact hints at time ``t``."""
        q = self.upper_body(t)
        q[:3] = self.pelvis(t)
        held = self._held_side(t)
        segments = list(_UPPER_BODY)
        if held is not None:  # the free leg's thigh and shank guide the solve into the pose
            side, w = held
            angles = self.model.joint_angles(q)
            angles.update({f"j{side}Hip_flex": w * _HELD_DEG[0], f"j{side}Knee_flex":
                           w * _HELD_DEG[1], f"j{side}Ankle_flex": w * _HELD_DEG[2]})
            q = self.model.configuration(angles, p_world_pelvis=q[:3],
                                         R_world_pelvis=self.model.segment_rotation(q, "Pelvis"))
            segments += [f"{side}UpperLeg", f"{side}LowerLeg"]
        data = self.model.forward(q)
        orientations = {s: data.oMf[self.model.segment_frame_id(s)].rotation.copy()
                        for s in segments}
        R_pelvis = data.oMf[self.model.segment_frame_id("Pelvis")].rotation
        feet = []
        for side in SIDES:
            foot = self.foot_targets(side, t)
            if held is None or held[0] != side:  # knees bend forward, not backwards
                hip = data.oMf[self.model.segment_frame_id(f"{side}UpperLeg")].translation
                orientations.update(self._leg(side, hip, foot.p_world_ankle, R_pelvis))
            orientations.update(foot.orientations)
            feet.append(foot)
        return feet_frame(t, orientations, feet, q[:3].copy(), root_position_weight=1e4)


def _hermite(t: float, a: float, b: float, x0: Any, v0: Any, x1: Any, v1: Any) -> Any:
    """Cubic from ``x0`` with velocity ``v0`` at ``a`` to ``x1`` with ``v1`` at ``b``."""
    h = b - a
    u = (t - a) / h
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    return h00 * x0 + h10 * h * v0 + h01 * x1 + h11 * h * v1
