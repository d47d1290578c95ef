"""N-pose geometry and mass properties of the 23-segment body.

Everything here is expressed in the world frame of the N-pose: the subject stands upright on
z = 0, arms along the body, thumbs forward, facing +X (X forward, Y left, Z up), with the pelvis
origin (midpoint of the hip joint centres) at x = y = 0. In this pose every segment frame is
parallel to the world, so a joint's offset from its parent segment origin is a plain difference
of world positions [m].

Segment masses, centre-of-mass locations and radii of gyration follow P. de Leva, "Adjustments
to Zatsiorsky-Seluyanov's segment inertia parameters", J. Biomech. 29(9), 1996 (male values);
the trunk is split over Pelvis (lower trunk), L5/L3/T12 (middle trunk) and T8 plus the two
shoulder segments (upper trunk).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .body import Body
from .joints import SEGMENTS, load_joint_specs

#: Segments that can carry an IMU; each has a sensor site named like the segment.
SENSOR_SEGMENTS: tuple[str, ...] = (
    "Pelvis", "T8", "Head",
    "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
    "RightUpperLeg", "RightLowerLeg", "RightFoot",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot",
)
#: UWB tag sites.
TAG_SITES: tuple[str, ...] = ("HeadTop", "LeftFootTop", "RightFootTop")
#: Foot contact points.
CONTACT_SITES: tuple[str, ...] = ("LeftHeel", "LeftToe", "RightHeel", "RightToe")
#: Contact points beyond the feet, where the body rests when kneeling, crawling or in a
#: cartwheel: the front of each knee (top of the tibia) and the palm of each hand.
BODY_CONTACT_SITES: tuple[str, ...] = ("LeftKnee", "RightKnee", "LeftPalm", "RightPalm")
#: Contact points where a lying or sitting body rests on the floor: the sacrum and the two
#: buttocks (sitting, lying on the back) on the pelvis; the shoulder blades (lying on the back)
#: and the chest (lying face down) on the upper trunk. (Elbows are not among them: in the
#: motion library they never carry the body, they brush the floor as a crawl's arm swings or are
#: swung lowest as a body rises, and held there they cost 0.2-1 cm of head position.)
TRUNK_CONTACT_SITES: tuple[str, ...] = (
    "Sacrum", "LeftButtock", "RightButtock", "LeftShoulderBlade", "RightShoulderBlade",
    "Chest")

#: The heel lies behind the ankle joint by this fraction of the foot length (the toe tip lies
#: ahead of it by the rest); BVH skeletons, which have no heel, are scaled with the same rule.
HEEL_BEHIND_ANKLE = 0.22

# de Leva (1996) male: mass fraction, CoM fraction from the proximal joint toward the distal
# point, radii of gyration / length about the segment's X (antero-posterior), Y (medio-lateral)
# and Z (longitudinal) axes.
_MASS_TABLE: dict[str, tuple[float, float, float, float, float]] = {
    "Pelvis": (0.1117, 0.40, 0.551, 0.615, 0.587),
    "L5": (0.0540, 0.50, 0.383, 0.482, 0.468),
    "L3": (0.0540, 0.50, 0.383, 0.482, 0.468),
    "T12": (0.0553, 0.50, 0.383, 0.482, 0.468),
    "T8": (0.1196, 0.50, 0.454, 0.716, 0.659),
    "Neck": (0.0138, 0.50, 0.376, 0.362, 0.312),
    "Head": (0.0556, 0.50, 0.376, 0.362, 0.312),
    "RightShoulder": (0.0200, 0.50, 0.300, 0.300, 0.150),
    "RightUpperArm": (0.0271, 0.5772, 0.269, 0.285, 0.158),
    "RightForeArm": (0.0162, 0.4574, 0.265, 0.276, 0.121),
    "RightHand": (0.0061, 0.36, 0.513, 0.628, 0.401),
    "RightUpperLeg": (0.1416, 0.4095, 0.329, 0.329, 0.149),
    "RightLowerLeg": (0.0433, 0.4459, 0.249, 0.255, 0.103),
    "RightFoot": (0.0117, 0.45, 0.245, 0.257, 0.124),
    "RightToe": (0.0020, 0.50, 0.300, 0.300, 0.300),
}


@dataclass(frozen=True)
class SegmentMass:
    """Mass properties of one segment.

    Attributes:
        mass: [kg].
        com: Centre of mass in the segment frame [m].
        inertia_diag: Principal moments about the centre of mass, along the segment axes [kg m^2].
    """

    mass: float
    com: np.ndarray
    inertia_diag: np.ndarray


@dataclass(frozen=True)
class Site:
    """A fixed frame on a segment, parallel to the segment frame.

    Attributes:
        name: Site name (SPEC section 2).
        segment: Segment that carries it.
        p_segment_site: Position in the segment frame [m].
        kind: ``"sensor"``, ``"tag"`` or ``"contact"``.
    """

    name: str
    segment: str
    p_segment_site: np.ndarray
    kind: str


@dataclass(frozen=True)
class BodyLayout:
    """The body in the N-pose.

    Attributes:
        p_world_origin: Segment name -> origin (its proximal joint; Pelvis: hip midpoint) [m].
        p_world_tip: Segment name -> distal point used for lengths and mass properties [m].
        sites: Site name -> :class:`Site`.
        masses: Segment name -> :class:`SegmentMass`.
    """

    p_world_origin: dict[str, np.ndarray]
    p_world_tip: dict[str, np.ndarray]
    sites: dict[str, Site]
    masses: dict[str, SegmentMass]

    def joint_offset(self, joint: str) -> np.ndarray:
        """Offset of a joint from its parent segment origin, in the parent frame [m]."""
        spec = load_joint_specs()[joint]
        return self.p_world_origin[spec.child] - self.p_world_origin[spec.parent]


def build_layout(body: Body) -> BodyLayout:
    """Place every segment origin, tip and site of ``body`` in the N-pose world frame."""
    origin, tip = _skeleton_points(body)
    sites = _sites(body, origin, tip)
    masses = {seg: _segment_mass(body, seg, origin, tip) for seg in SEGMENTS}
    return BodyLayout(origin, tip, sites, masses)


def _side(segment: str) -> float:
    """+1 for left segments (world +Y in the N-pose), -1 for right, 0 on the midline."""
    if segment.startswith("Left"):
        return 1.0
    if segment.startswith("Right"):
        return -1.0
    return 0.0


def _skeleton_points(body: Body) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    H = body.height
    d = body.dimension
    hip_z = d("hip_height")
    shoulder_z = d("shoulder_height")
    p = {}
    tip = {}
    p["Pelvis"] = np.array([0.0, 0.0, hip_z])
    l5s1 = np.array([-0.010 * H, 0.0, hip_z + 0.057 * H])
    c1 = np.array([-0.005 * H, 0.0, 0.910 * H])
    c7 = np.array([-0.020 * H, 0.0, min(shoulder_z + 0.025 * H, c1[2] - 0.03 * H)])
    for seg, frac in (("L5", 0.0), ("L3", 0.22), ("T12", 0.44), ("T8", 0.66)):
        p[seg] = l5s1 + frac * (c7 - l5s1)
    p["Neck"] = c7
    p["Head"] = c1
    tip["Pelvis"] = p["L5"]
    tip["L5"], tip["L3"], tip["T12"], tip["T8"] = p["L3"], p["T12"], p["T8"], c7
    tip["Neck"] = c1
    tip["Head"] = np.array([0.0, 0.0, H])
    for side_name in ("Right", "Left"):
        s = 1.0 if side_name == "Left" else -1.0
        sc = np.array([0.030 * H, s * 0.015 * H, shoulder_z - 0.015 * H])
        gh = np.array([0.0, s * d("shoulder_width") / 2.0, shoulder_z])
        elbow = gh - [0.0, 0.0, d("upper_arm")]
        wrist = elbow - [0.0, 0.0, d("forearm")]
        p[f"{side_name}Shoulder"], tip[f"{side_name}Shoulder"] = sc, gh
        p[f"{side_name}UpperArm"], tip[f"{side_name}UpperArm"] = gh, elbow
        p[f"{side_name}ForeArm"], tip[f"{side_name}ForeArm"] = elbow, wrist
        p[f"{side_name}Hand"], tip[f"{side_name}Hand"] = wrist, wrist - [0.0, 0.0, d("hand")]
        y = s * d("hip_width") / 2.0
        hip = np.array([0.0, y, hip_z])
        knee = hip - [0.0, 0.0, d("upper_leg")]
        ankle = np.array([0.0, y, d("ankle_height")])
        heel_x = -HEEL_BEHIND_ANKLE * d("foot_length")
        ball = np.array([heel_x + 0.72 * d("foot_length"), y, 0.012 * H])
        p[f"{side_name}UpperLeg"], tip[f"{side_name}UpperLeg"] = hip, knee
        p[f"{side_name}LowerLeg"], tip[f"{side_name}LowerLeg"] = knee, ankle
        p[f"{side_name}Foot"], tip[f"{side_name}Foot"] = ankle, ball
        p[f"{side_name}Toe"] = ball
        tip[f"{side_name}Toe"] = np.array([heel_x + d("foot_length"), y, 0.0])
    return p, tip


def _sites(body: Body, origin: dict[str, np.ndarray], tip: dict[str, np.ndarray]) -> dict[
        str, Site]:
    H = body.height
    fl = body.dimension("foot_length")
    world: dict[str, tuple[str, np.ndarray, str]] = {}

    def mid(seg: str, frac: float) -> np.ndarray:
        return origin[seg] + frac * (tip[seg] - origin[seg])

    world["HeadTop"] = ("Head", np.array([0.0, 0.0, H]), "tag")
    world["Pelvis"] = ("Pelvis", origin["Pelvis"] + [-0.060 * H, 0.0, 0.030 * H], "sensor")
    world["T8"] = ("T8", mid("T8", 0.4) + [-0.075 * H, 0.0, 0.0], "sensor")
    world["Head"] = ("Head", np.array([-0.055 * H, 0.0, 0.950 * H]), "sensor")
    for side_name in ("Right", "Left"):
        s = _side(side_name)
        lateral = np.array([0.0, s, 0.0])
        ankle = origin[f"{side_name}Foot"]
        heel_x = -0.22 * fl
        world[f"{side_name}FootTop"] = (
            f"{side_name}Foot", np.array([heel_x + 0.45 * fl, ankle[1], 0.040 * H]), "tag")
        world[f"{side_name}Heel"] = (
            f"{side_name}Foot", np.array([heel_x, ankle[1], 0.0]), "contact")
        world[f"{side_name}Toe"] = (f"{side_name}Toe", tip[f"{side_name}Toe"].copy(), "contact")
        world[f"{side_name}Shoulder"] = (
            f"{side_name}Shoulder", mid(f"{side_name}Shoulder", 0.6) + [-0.06 * H, 0.0, -0.02 * H],
            "sensor")
        world[f"{side_name}UpperArm"] = (
            f"{side_name}UpperArm", mid(f"{side_name}UpperArm", 0.5) + 0.025 * H * lateral,
            "sensor")
        world[f"{side_name}ForeArm"] = (
            f"{side_name}ForeArm", mid(f"{side_name}ForeArm", 0.75) + 0.020 * H * lateral, "sensor")
        world[f"{side_name}Hand"] = (
            f"{side_name}Hand", mid(f"{side_name}Hand", 0.3) + 0.015 * H * lateral, "sensor")
        world[f"{side_name}UpperLeg"] = (
            f"{side_name}UpperLeg", mid(f"{side_name}UpperLeg", 0.5) + 0.050 * H * lateral,
            "sensor")
        world[f"{side_name}LowerLeg"] = (
            f"{side_name}LowerLeg",
            mid(f"{side_name}LowerLeg", 0.4) + [0.030 * H, -0.015 * H * s, 0.0], "sensor")
        world[f"{side_name}Foot"] = (
            f"{side_name}Foot", np.array([heel_x + 0.55 * fl, ankle[1], 0.033 * H]), "sensor")
    for side_name in ("Left", "Right"):
        # the tibial tuberosity: in front of the shin just below the knee joint (kneeling)
        world[f"{side_name}Knee"] = (
            f"{side_name}LowerLeg", origin[f"{side_name}LowerLeg"] + [0.030 * H, 0.0, -0.040 * H],
            "contact")
    for side_name in ("Left", "Right"):
        # the middle of the palm, on the inner side of the hand (N-pose: palms face the body)
        inward = np.array([0.0, -_side(side_name), 0.0])
        world[f"{side_name}Palm"] = (
            f"{side_name}Hand", mid(f"{side_name}Hand", 0.4) + 0.010 * H * inward, "contact")
    world.update(_trunk_contacts(H, origin, tip))
    return {name: Site(name, seg, p - origin[seg], kind) for name, (seg, p, kind) in world.items()}


def _trunk_contacts(H: float, origin: dict[str, np.ndarray], tip: dict[str, np.ndarray]
                    ) -> dict[str, tuple[str, np.ndarray, str]]:
    """The :data:`TRUNK_CONTACT_SITES`: segment, N-pose world position [m] and kind of each.

    On the body's surface as the pelvis and T8 sensor sites are (the back of the trunk lies
    0.06-0.075 ``H`` behind the hip joint centres; the chest is 0.13 ``H`` deep).
    """
    pelvis, t8 = origin["Pelvis"], origin["T8"]
    out = {
        # the back of the sacrum, just below the pelvis sensor; a lying body rests on it
        "Sacrum": ("Pelvis", pelvis + [-0.065 * H, 0.0, 0.010 * H], "contact"),
        # the chest over the sternum, a third of the way up the upper trunk (lying face down)
        "Chest": ("T8", t8 + (tip["T8"] - t8) / 3.0 + [0.075 * H, 0.0, 0.0], "contact")}
    for side_name in ("Left", "Right"):
        s = _side(side_name)
        # the bottom of each buttock, behind and below the hip joint (sitting on the floor)
        out[f"{side_name}Buttock"] = (
            "Pelvis", pelvis + [-0.050 * H, s * 0.045 * H, -0.040 * H], "contact")
        # each shoulder blade on the back of the upper trunk (lying on the back)
        out[f"{side_name}ShoulderBlade"] = (
            "T8", t8 + (tip["T8"] - t8) / 2.0 + [-0.070 * H, s * 0.050 * H, 0.0], "contact")
    return out


def _segment_mass(body: Body, segment: str, origin: dict[str, np.ndarray],
                  tip: dict[str, np.ndarray]) -> SegmentMass:
    key = segment.replace("Left", "Right")
    frac, com_frac, rx, ry, rz = _MASS_TABLE[key]
    mass = frac * body.dimension("mass")
    axis = tip[segment] - origin[segment]
    length = float(np.linalg.norm(axis))
    com = com_frac * axis
    inertia = mass * (np.array([rx, ry, rz]) * length) ** 2
    return SegmentMass(mass, com, inertia)
