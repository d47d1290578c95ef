"""Procedural walking: footsteps along a path, rolling feet, arm swing, solved into configurations.

The walk is planned in Cartesian space and turned into model configurations with the solver
itself, so the ground truth is a kinematically exact motion of the model:

* a path (straight, a circle, or straight legs joined by turns) walked at a speed that ramps up
  smoothly after a standing N-pose;
* footprints: each foot lands where the pelvis will be 22 % of a gait cycle later, beside the
  path; each stance rolls over the heel (heel rocker), stays flat, then rolls over the ball of
  the foot with the toes flat (heel-off; with ``toe_roll_deg`` the toe rolls over its tip as
  well, the ball rising as in brisk mocap walks); each swing follows a smooth arc with clearance;
* pelvis bobbing, sway and rotation, thorax counter-rotation, arm swing, elbow flexion;
* contact phases (heel and toe separately) are given to the solver as hints, so planted points
  are held exactly (hard no-slip constraints) and the truth never slides;
* variations beyond a forward walk: the body may face away from the walking direction
  (``facing_deg``: 180 walks backwards, 90 side-steps), and the walk may pause (``pauses``): the
  gait clock slows down, holds still in a double stance (front foot flat, rear foot on its
  toes) and starts again. A tiny circle is a turn on the spot. :data:`GAIT_PRESETS` names them.

All positions in metres, angles in degrees where named ``_deg``; world frame Z up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from tqdm import tqdm

from ..ik.frame import Frame
from ..ik.solver import Solver
from ..mocap.model_motion import TruthMotion
from ..model.human_model import HumanModel
from ..rotations import axis_rotation

_CONTACTS = ("LeftHeel", "LeftToe", "RightHeel", "RightToe")
#: The feet, in the order their targets enter a frame.
SIDES = ("Right", "Left")
#: Segments whose orientation the plan dictates (legs follow from the feet positions).
_UPPER_BODY = ("Pelvis", "T8", "Neck", "Head", "RightShoulder", "RightUpperArm", "RightForeArm",
               "RightHand", "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand")


@dataclass(frozen=True)
class GaitParameters:
    """A walk.

    Attributes:
        path: ``"straight"``, ``"circle"`` or ``"turns"`` (straight legs joined by 90 deg turns).
        speed: Walking speed [m/s].
        step_length: Distance between consecutive footprints along the path [m].
        duration: Total duration including the standing start [s].
        stand: Standing N-pose at the start [s].
        radius: Circle (or turn) radius [m].
        leg_length: Straight legs of the ``"turns"`` path [m].
        clearance: Peak foot lift in swing [m].
        heel_strike_deg: Foot pitch (toes up) at heel strike [deg].
        toe_off_deg: Foot pitch (heel up) at toe-off [deg].
        toe_roll_deg: Toe pitch (ball up) at toe-off [deg]: 0 keeps the toes flat on the floor
            while the foot rolls over the ball; more rolls the toe over its tip as the heel
            rises (the ball lifts, as in brisk mocap walks) and the toe lifts off pitched.
        arm_swing_deg: Shoulder flexion amplitude [deg].
        start_heading_deg: Initial walking direction [deg] (0 = +X).
        facing_deg: Body heading relative to the walking direction [deg]: 0 forward, 180
            backwards, +90 side steps towards the body's right (the body faces left of the
            path).
        pauses: Stops as ``(time, length)`` pairs [s]: around ``time`` the walk slows to a halt
            within ``pause_ramp`` s, stands still for ``length`` s and starts again. The halt is
            moved to the nearest double stance.
        pause_ramp: Time to slow down from full speed to a halt, and back [s].
        bounce: ``""`` walks; ``"hop"`` (right leg), ``"skip"`` or ``"jump"`` (both feet)
            bounce with flight phases (:mod:`ikfusion.sim.bounce`).
        contact_time: Stance of each bounce [s].
        flight_time: Flight of each bounce [s] (apex ``9.81 flight_time^2 / 8`` m above
            take-off).
    """

    path: str = "straight"
    speed: float = 1.2
    step_length: float = 0.65
    duration: float = 10.0
    stand: float = 2.0
    radius: float = 2.0
    leg_length: float = 3.0
    clearance: float = 0.04
    heel_strike_deg: float = 15.0
    toe_off_deg: float = 30.0
    toe_roll_deg: float = 0.0
    heel_off: float = 0.75
    stance: float = 0.6
    arm_swing_deg: float = 18.0
    start_heading_deg: float = 0.0
    facing_deg: float = 0.0
    pauses: tuple[tuple[float, float], ...] = ()
    pause_ramp: float = 1.2
    bounce: str = ""
    contact_time: float = 0.3
    flight_time: float = 0.2

    @property
    def cycle(self) -> float:
        """Gait cycle (stride) duration [s]."""
        return 2.0 * self.step_length / self.speed


#: Named walks and bouncing gaits of ``simulate --motion gait:<name>`` (each fits a 6 x 8 m room):
#: keyword arguments of :class:`GaitParameters` besides ``duration`` and ``stand``. Faster
#: walks (1.5 m/s and more) or tighter turns (radius 1 m and less) make the generator's solve
#: jump now and then (the pelvis moves centimetres in one frame): the presets stay below that.
GAIT_PRESETS: dict[str, dict[str, Any]] = {
    "circle": {"path": "circle", "radius": 1.5, "speed": 1.1, "step_length": 0.6},
    "straight": {"path": "straight", "radius": 1.5, "speed": 1.1, "step_length": 0.6},
    "turns": {"path": "turns", "leg_length": 1.5, "radius": 1.5, "speed": 1.1,
              "step_length": 0.6},
    "slow": {"path": "circle", "radius": 1.5, "speed": 0.6, "step_length": 0.45},
    "fast": {"path": "circle", "radius": 2.0, "speed": 1.4, "step_length": 0.6,
             "arm_swing_deg": 25.0},
    "backwards": {"path": "circle", "radius": 1.5, "speed": 0.6, "step_length": 0.4,
                  "facing_deg": 180.0, "heel_strike_deg": 5.0, "toe_off_deg": 15.0,
                  "arm_swing_deg": 8.0},
    "sidestep": {"path": "circle", "radius": 1.5, "speed": 0.35, "step_length": 0.15,
                 "facing_deg": 90.0, "heel_strike_deg": 0.0, "toe_off_deg": 10.0,
                 "clearance": 0.05, "arm_swing_deg": 4.0},
    "turn-on-spot": {"path": "circle", "radius": 0.1, "speed": 0.08, "step_length": 0.05,
                     "heel_strike_deg": 0.0, "toe_off_deg": 10.0, "clearance": 0.05,
                     "arm_swing_deg": 4.0},
    "start-stop": {"path": "turns", "leg_length": 1.5, "radius": 1.5, "speed": 1.1,
                   "step_length": 0.6, "pauses": tuple((t, 2.0) for t in range(7, 600, 7))},
    # bouncing gaits with flight phases (ikfusion.sim.bounce)
    "hop": {"bounce": "hop", "path": "circle", "radius": 1.5, "speed": 0.5,
            "step_length": 0.225, "contact_time": 0.25, "flight_time": 0.2, "clearance": 0.03,
            "arm_swing_deg": 6.0},
    "skip": {"bounce": "skip", "path": "circle", "radius": 1.5, "speed": 0.9,
             "step_length": 0.72, "contact_time": 0.22, "flight_time": 0.18, "clearance": 0.05,
             "arm_swing_deg": 20.0},
    "jump": {"bounce": "jump", "path": "circle", "radius": 1.5, "speed": 0.3,
             "step_length": 0.2, "contact_time": 0.35, "flight_time": 0.3, "clearance": 0.03,
             "arm_swing_deg": 6.0},
}


def gait_preset(name: str, duration: float, stand: float = 2.0) -> GaitParameters:
    """The walk ``name`` of :data:`GAIT_PRESETS`, lasting ``duration`` [s] after ``stand`` [s].

    Raises:
        ValueError: An unknown name (the message lists the known ones).
    """
    if name not in GAIT_PRESETS:
        raise ValueError(f"unknown walk {name!r}; use one of {', '.join(GAIT_PRESETS)}")
    return GaitParameters(duration=duration, stand=stand, **GAIT_PRESETS[name])


@dataclass(frozen=True)
class FootTargets:
    """One foot's targets at an instant (world frame).

    Attributes:
        p_world_ankle: Ankle position (3,) [m].
        orientations: ``<side>Foot`` and ``<side>Toe`` -> ``R_world_segment`` (3, 3).
        positions: ``<side>Heel`` and ``<side>Toe`` contact points -> ``p_world_site`` (3,) [m].
        contacts: The same contact points -> planted.
    """

    p_world_ankle: np.ndarray
    orientations: dict[str, np.ndarray]
    positions: dict[str, np.ndarray]
    contacts: dict[str, bool]


def feet_frame(time: float, orientations: dict[str, np.ndarray], feet: list[FootTargets],
               root_position: np.ndarray, root_position_weight: float) -> Frame:
    """A planner's frame: ``orientations`` (feet included) and the feet's contact points.

    The contact points are held firmly (weight 1e4 [1/m^2]) and their contact phases given as
    hints; the feet and toes are tracked with weight 10.

    Args:
        time: [s].
        orientations: Segment name -> ``R_world_segment`` (3, 3), the feet's among them.
        feet: The feet's targets.
        root_position: Target of the pelvis origin ``p_world_pelvis`` (3,) [m].
        root_position_weight: Its weight [1/m^2].
    """
    positions = {name: p for foot in feet for name, p in foot.positions.items()}
    hints = {name: on for foot in feet for name, on in foot.contacts.items()}
    weights: dict[str, float | np.ndarray] = dict.fromkeys(positions, 1e4)
    orientation_weights = {name: 10.0 for foot in feet for name in foot.orientations}
    return Frame(time, orientations, positions, hints, orientation_weights=orientation_weights,
                 position_weights=weights, root_position=root_position,
                 root_position_weight=root_position_weight)


class _Path:
    """Arc-length parametrised path in the floor plane: position (x, y) [m] and heading [rad]."""

    def __init__(self, p: GaitParameters) -> None:
        self.p = p
        self.heading0 = np.radians(p.start_heading_deg)

    def _local(self, s: float) -> tuple[np.ndarray, float]:
        p = self.p
        if p.path == "straight":
            return np.array([s, 0.0]), 0.0
        if p.path == "circle":
            a = s / p.radius
            return np.array([p.radius * np.sin(a), p.radius * (1.0 - np.cos(a))]), a
        if p.path == "turns":
            pos, heading = np.zeros(2), 0.0
            arc = 0.5 * np.pi * p.radius
            remaining = s
            while True:
                straight = min(remaining, p.leg_length)
                pos = pos + straight * np.array([np.cos(heading), np.sin(heading)])
                remaining -= straight
                if remaining <= 0.0:
                    return pos, heading
                a = min(remaining, arc) / p.radius
                centre = pos + p.radius * np.array([-np.sin(heading), np.cos(heading)])
                heading_new = heading + a
                pos = centre + p.radius * np.array([np.sin(heading_new), -np.cos(heading_new)])
                heading = heading_new
                remaining -= a * p.radius
                if remaining <= 0.0:
                    return pos, heading
        raise ValueError(f"unknown path {p.path!r}; use straight, circle or turns")

    def at(self, s: float) -> tuple[np.ndarray, float]:
        pos, heading = self._local(s)
        R = axis_rotation("z", self.heading0)[:2, :2]
        return R @ pos, heading + self.heading0


def _smoothstep(x: np.ndarray | float) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)


class GaitPlanner:
    """Plans every target of a walk; :func:`generate_gait` solves it into configurations.

    Args:
        model: The human model (its body sets the foot geometry and leg reach).
        parameters: The walk.
    """

    def __init__(self, model: HumanModel, parameters: GaitParameters) -> None:
        self.model = model
        self.p = parameters
        self.path = _Path(parameters)
        q0 = model.neutral()
        self.pelvis_height = float(q0[2])
        ankle = model.segment_position(q0, "RightFoot")
        ball = model.segment_position(q0, "RightToe")
        heel = model.site_position(q0, "RightHeel")
        toe = model.site_position(q0, "RightToe")
        self.ankle_height = float(ankle[2])
        self.half_width = float(abs(ankle[1]))
        # Foot geometry in the foot frame (flat foot, ankle at the origin).
        self.heel_local = heel - ankle
        self.ball_local = ball - ankle
        self.toe_in_toe = toe - ball
        self.ramp = 1.0
        self._s_grid = np.linspace(0.0, parameters.duration + 2 * parameters.cycle, 4000)
        v = parameters.speed * _smoothstep((self._s_grid - parameters.stand) / self.ramp)
        self._dist = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(
            self._s_grid))])
        self._clock_t, self._clock_c = self._gait_clock()

    # ---------------------------------------------------------------- timing
    def _gait_clock(self) -> tuple[np.ndarray, np.ndarray]:
        """Time [s] -> gait clock [s] table: the clock stands still during the pauses."""
        p = self.p
        T = p.cycle
        n = max(int(p.duration * 200), 2)
        t = np.linspace(0.0, p.duration, n)
        rate = np.ones(n)
        lag = 0.0  # how far the clock is behind the time [s]
        for start, length in sorted(p.pauses):
            # the halt: the clock at a double stance (front foot flat, rear foot on its toes)
            k = np.round((start - lag - p.stand - 0.49 * T) / T)
            halt = p.stand + (k + 0.49) * T
            if halt <= p.stand + T:
                continue
            # the rate falls from 1 to 0 over the ramp (the clock advances ramp/2 meanwhile),
            # stays 0 for ``length``, and rises back to 1
            t_stop = halt + lag - 0.5 * p.pause_ramp
            x_down = (t - t_stop) / p.pause_ramp
            x_up = (t - t_stop - p.pause_ramp - length) / p.pause_ramp
            rate -= _smoothstep(x_down) - _smoothstep(x_up)
            lag += p.pause_ramp + length
        rate = np.clip(rate, 0.0, 1.0)  # pauses closer than their ramps merge
        clock = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
        return t, clock

    def clock(self, t: float) -> float:
        """The gait clock at time ``t`` [s]: the time the walk has advanced to."""
        if not self.p.pauses:
            return t
        return float(np.interp(t, self._clock_t, self._clock_c, right=t - (
            self._clock_t[-1] - self._clock_c[-1])))

    def distance(self, t: float) -> float:
        """Arc length walked by the pelvis at time ``t`` [m]."""
        return float(np.interp(t, self._s_grid, self._dist))

    def _tau(self, t: float) -> float:
        return t - self.p.stand

    def footprint(self, side: str, k: int) -> tuple[np.ndarray, float]:
        """Flat-foot ankle position (x, y, z) and yaw of footprint ``k`` (-1: standing)."""
        T = self.p.cycle
        if k < 0:
            s = 0.0
        else:
            land = (1.0 - self.p.stance + (0.0 if side == "Right" else 0.5)) * T + k * T
            s = self.distance(self.p.stand + land + 0.22 * T)
        return self.beside_path(side, s)

    def beside_path(self, side: str, s: float) -> tuple[np.ndarray, float]:
        """Flat-foot ankle position (x, y, z) [m] and yaw [rad] of a foot at arc length ``s``.

        The foot stands ``half_width`` to the ``side`` of the path, turned with the body.
        """
        c, heading = self.path.at(s)
        body = heading + np.radians(self.p.facing_deg)
        lateral = np.array([-np.sin(body), np.cos(body)])
        sign = 1.0 if side == "Left" else -1.0
        xy = c + sign * self.half_width * lateral
        return np.array([xy[0], xy[1], self.ankle_height]), body

    def _phase(self, side: str, t: float) -> tuple[str, int, float]:
        """(``"stance"`` or ``"swing"``, footprint index, fraction of the phase)."""
        T = self.p.cycle
        tau = self._tau(t)
        off = 0.0 if side == "Right" else 0.5 * T
        rel = tau - off  # toe-off of swing k happens at rel = k T
        st, sw = self.p.stance * T, (1.0 - self.p.stance) * T
        if rel < 0.0:
            return "stance", -1, 1.0 + rel / st if rel > -st else 0.0
        k = int(np.floor(rel / T))
        within = rel - k * T
        if within < sw:
            return "swing", k, within / sw
        return "stance", k, (within - sw) / st

    # ---------------------------------------------------------------- foot poses
    def _pose_about(self, pivot_local: np.ndarray, p_ankle_flat: np.ndarray, yaw: float,
                    pitch: float) -> tuple[np.ndarray, np.ndarray]:
        """Foot pose rotated by ``pitch`` about a point of the flat foot (kept fixed)."""
        R_yaw = axis_rotation("z", yaw)
        R = R_yaw @ axis_rotation("y", pitch)
        pivot = p_ankle_flat + R_yaw @ pivot_local
        return R, pivot - R @ pivot_local

    def foot(self, side: str, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, bool]:
        """``(R_world_foot, p_world_ankle, R_world_toe, heel_contact, toe_contact)``."""
        phase, k, f = self._phase(side, t)
        hs = -np.radians(self.p.heel_strike_deg)
        to = np.radians(self.p.toe_off_deg)
        roll = np.radians(self.p.toe_roll_deg)
        if phase == "stance":
            p_flat, yaw = self.footprint(side, k)
            R_toe = axis_rotation("z", yaw)
            standing_start = k < 0 and self._tau(t) < -self.p.stance * self.p.cycle
            if f < 1.0 / 6.0 and k >= 0:  # heel rocker
                pitch = hs * (1.0 - _smoothstep(6.0 * f))
                R, pa = self._pose_about(self.heel_local, p_flat, yaw, float(pitch))
                return R, pa, R, True, False  # the toes touch down when the foot is flat
            h = self.p.heel_off
            if f < h or standing_start:
                return R_toe, p_flat, R_toe, True, True
            g = float(_smoothstep((f - h) / (1.0 - h)))  # heel-off about the ball (and tip)
            R, pa, R_toe = self._push_off_pose(p_flat, yaw, to * g, roll * g)
            return R, pa, R_toe, to * g < np.radians(2.0), True
        start, yaw0 = self.footprint(side, k - 1)
        end, yaw1 = self.footprint(side, k)
        R0, p0, _ = self._push_off_pose(start, yaw0, to, roll)
        R1, p1 = self._pose_about(self.heel_local, end, yaw1, hs)
        w = float(_smoothstep(f))
        p = (1.0 - w) * p0 + w * p1
        p[2] += self.p.clearance * np.sin(np.pi * f) ** 2 * 2.0
        yaw = yaw0 + w * np.angle(np.exp(1j * (yaw1 - yaw0)))
        pitch = (1.0 - w) * to + w * hs
        R = axis_rotation("z", yaw) @ axis_rotation("y", pitch)
        toe_relax = float(_smoothstep(f / 0.5))
        R_toe = R @ axis_rotation("y", -(1.0 - toe_relax) * (to - roll))
        return R, p, R_toe, False, False

    def _push_off_pose(self, p_ankle_flat: np.ndarray, yaw: float, pitch: float,
                       toe_pitch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(R_world_foot, p_world_ankle, R_world_toe)`` of a foot on its toe tip.

        The toe turned by ``toe_pitch`` [rad] (ball up) about its tip, which stays where the
        flat foot puts it; the foot pitched by ``pitch`` [rad] (heel up) about the ball.
        """
        R_yaw = axis_rotation("z", yaw)
        tip = p_ankle_flat + R_yaw @ (self.ball_local + self.toe_in_toe)
        R_toe = R_yaw @ axis_rotation("y", toe_pitch)
        ball = tip - R_toe @ self.toe_in_toe
        R = R_yaw @ axis_rotation("y", pitch)
        return R, ball - R @ self.ball_local, R_toe

    def contact_points(self, R_foot: np.ndarray, p_ankle: np.ndarray,
                       R_toe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World heel and toe-tip positions of a foot pose."""
        heel = p_ankle + R_foot @ self.heel_local
        ball = p_ankle + R_foot @ self.ball_local
        return heel, ball + R_toe @ self.toe_in_toe

    def foot_targets(self, side: str, t: float) -> FootTargets:
        """The targets and contact hints of the ``side`` foot at ``t`` [s] (see :meth:`foot`)."""
        R_foot, p_ankle, R_toe, heel_on, toe_on = self.foot(side, t)
        heel, toe = self.contact_points(R_foot, p_ankle, R_toe)
        return FootTargets(p_ankle, {f"{side}Foot": R_foot, f"{side}Toe": R_toe},
                           {f"{side}Heel": heel, f"{side}Toe": toe},
                           {f"{side}Heel": heel_on, f"{side}Toe": toe_on})

    # ---------------------------------------------------------------- upper body
    def upper_body(self, t: float) -> np.ndarray:
        """A configuration whose upper-body segments give the orientation targets."""
        T = self.p.cycle
        tau = self._tau(t)
        walking = float(_smoothstep(tau / self.ramp)) if tau > 0 else 0.0
        phase = 2.0 * np.pi * (tau - (1.0 - self.p.stance) * T) / T  # 0 at right heel strike
        s = self.distance(t)
        c, heading = self.path.at(s)
        arm = self.p.arm_swing_deg * walking
        angles = {
            "jRightShoulder_flex": -arm * np.cos(phase), "jLeftShoulder_flex": arm * np.cos(phase),
            "jRightShoulder_abd": 5.0 * walking, "jLeftShoulder_abd": 5.0 * walking,
            "jRightElbow_flex": walking * (25.0 - 8.0 * np.cos(phase)),
            "jLeftElbow_flex": walking * (25.0 + 8.0 * np.cos(phase)),
            "jT9T8_rot": -4.0 * walking * np.cos(phase),
            "jL5S1_flex": 2.0 * walking,
            "jT1C7_rot": 3.0 * walking * np.cos(phase),
        }
        heading = heading + np.radians(self.p.facing_deg)
        pelvis_yaw = heading + np.radians(4.0 * walking * np.cos(phase))
        R_pelvis = (axis_rotation("z", pelvis_yaw)
                    @ axis_rotation("x", np.radians(-3.0 * walking * np.sin(phase)))
                    @ axis_rotation("y", np.radians(3.0 * walking)))
        lateral = np.array([-np.sin(heading), np.cos(heading)])
        sway = 0.02 * walking * np.sin(phase)
        z = self.pelvis_height - walking * (0.075 - 0.012 * np.cos(2.0 * phase))
        xy = c + sway * lateral
        return self.model.configuration(angles, p_world_pelvis=[xy[0], xy[1], z],
                                        R_world_pelvis=R_pelvis)

    def frame(self, t: float) -> Frame:
        """All targets and contact hints at time ``t``."""
        t_frame, t = t, self.clock(t)
        q = self.upper_body(t)
        data = self.model.forward(q)
        orientations = {s: data.oMf[self.model.segment_frame_id(s)].rotation.copy()
                        for s in _UPPER_BODY}
        feet = [self.foot_targets(side, t) for side in SIDES]
        for foot in feet:
            orientations.update(foot.orientations)
        return feet_frame(t_frame, orientations, feet, q[:3].copy(), root_position_weight=1e2)


def generate_gait(model: HumanModel, parameters: GaitParameters | None = None,
                  rate: float = 60.0, progress: bool = False) -> TruthMotion:
    """Generate a walk as exact model configurations.

    Args:
        model: The human model.
        parameters: The walk (defaults: 10 s straight at 1.2 m/s after a 2 s N-pose).
        rate: Sample rate [Hz].
        progress: Show a progress bar.

    Returns:
        The ground truth; ``info["parameters"]`` holds the walk.
    """
    p = parameters or GaitParameters()
    planner = GaitPlanner(model, p)
    if p.bounce:
        from .bounce import BouncePlanner  # it builds on GaitPlanner

        planner = BouncePlanner(model, p)
    # Converged truth; knees that move like the hinges they nearly are (ball joints otherwise
    # take up the foot placement with knee rotation and valgus no real knee shows); hard
    # limits: a truth stays inside its ranges.
    solver = Solver(model, max_iterations=8, step_tolerance=1e-3, joint_range_overshoot_deg=0.0,
                    posture_axes={f"j{s}Knee": [100.0, 1.0, 100.0] for s in ("Left", "Right")})
    times = np.arange(0.0, p.duration, 1.0 / rate)
    qs, contacts = [], []
    for t in tqdm(times, disable=not progress, unit="frame", desc="gait"):
        frame = planner.frame(float(t))
        pose = solver.step(frame)
        qs.append(pose.q)
        contacts.append([frame.contacts[c] for c in _CONTACTS])  # type: ignore[index]
    return TruthMotion(model, times, np.array(qs), list(_CONTACTS),
                       np.array(contacts, dtype=bool), f"gait:{p.path}", {"parameters": p})
