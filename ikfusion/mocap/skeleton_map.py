"""Map a BVH skeleton onto the 23 model segments (SPEC section 2) in the MVN segment convention.

What a BVH gives and what we need
---------------------------------
A BVH joint frame is whatever the exporter chose; with every channel at zero (the *rest pose*,
usually a T-pose) all joint frames are parallel to the file frame. We need, per frame, the world
orientation of each model segment in the MVN convention (SPEC section 1): with the subject in
the N-pose facing +X, every segment frame is parallel to the world (X forward, Y left, Z up).

How the mapping is built (:func:`build_skeleton_map`, once per skeleton)
------------------------------------------------------------------------
1. **Joints.** Limb joints are found by name (:func:`default_aliases`: CMU MotionBuilder and
   3ds Max conversions, SFU, MVN and MVN's BVH export, Mixamo and other ``namespace:`` prefixes,
   3ds Max Biped, Unity-like names; matching ignores case, spaces, ``_``, ``-``, ``.`` and any
   ``prefix:``). For each side the lower leg (knee) and forearm (elbow) are anchors; the upper
   leg / upper arm is the deepest name match above them (else their parent), so a name meaning
   "upper arm" in one convention and "clavicle" in another (``LeftShoulder``) is resolved by the
   tree. The trunk is found from the tree: T8 is the joint where the two arms branch, the lumbar
   joints lie between the pelvis and T8 (1 -> L5; 2 -> L5, T12; 3 -> L5, L3, T12; more ->
   first, middle, last), the neck between T8 and the head, a clavicle between T8 and an upper
   arm. Joints at the same place as their only child (zero offset, e.g. CMU's ``LeftFingerBase``
   under ``LeftHand``) are merged with it.
2. **Which BVH rotation a segment follows.** A segment follows the joint whose rotation moves
   its distal joint (the parent of the next segment's proximal joint, so twist/roll joints are
   included), or for an end segment (hand, toe, head) the deepest joint merged with it.
3. **Rest offsets** ``R_joint_segment``. In the rest pose the body frame ``B`` is built from the
   geometry: up = the file's up axis, left = right hip -> left hip (made horizontal), forward =
   left x up. The rest pose is then read as "the N-pose, except where a limb points elsewhere":
   legs, arms and hands get the smallest rotation that turns their N-pose direction (-Z, down)
   onto their rest direction (proximal joint -> distal joint), e.g. +-90 deg about the forward
   axis for T-pose arms and a few degrees for CMU's splayed rest legs; feet and toes get the
   heading of their rest direction (toe-out is kept, the foot's rest pitch is taken as flat
   ground); pelvis, spine, neck, head and clavicles are taken as in the N-pose (identity).
   So ``R_world_segment(rest) = R_world_B @ R_B_segment`` and, because every rest joint frame is
   the file frame, ``R_joint_segment = R_world_file.T @ R_world_B @ R_B_segment``.
4. **Per frame** ``R_world_segment(t) = R_world_joint(t) @ R_joint_segment`` with
   ``R_world_joint`` from the BVH forward kinematics in our Z-up world. For a rigid bone this
   puts the segment's long axis exactly on the proximal->distal joint line at every frame (the
   thigh's -Z goes from hip to knee), and the secondary axes follow the bone's own rotation.
5. **Level feet** (``level_feet=True``). A rest foot is often not level when the body stands:
   CMU's rest feet sit on splayed rest legs and stand tilted by about 30 deg once the legs are
   straight. When the clip has steps, each foot and toe frame is rebuilt in its BVH joint's
   frame: Z = the mean world up seen from that joint during flat-foot stance, X = the rest
   direction to its distal end (ankle -> toe joint, toe joint -> toe tip) made perpendicular to
   Z. The foot is then level on average in stance and still points where the toes point.

Note on Xsens MVN: MVN's own segment frames are world-parallel in a T-pose for the arms (its
identity pose holds the arms out; in MVNX files ``jLeftElbow`` lies on ``LeftUpperArm``'s +Y).
The SPEC's N-pose convention used here differs from them by a quarter turn about X on the upper
arms, forearms and hands (``R_ours = R_mvn @ Rx(+90 deg)`` on the left, ``Rx(-90 deg)`` on the
right); trunk, legs and clavicles are the same.

Missing segments (the BVH has fewer spine joints, no toes, no clavicles, no arms) are listed in
:attr:`MappedMotion.missing`. With ``fill=True`` (default) they still get an orientation: a trunk
segment between two mapped trunk segments is interpolated (slerp by its place in the chain
Pelvis, L5, L3, T12, T8, Neck, Head), any other copies its nearest mapped ancestor segment (that
joint held neutral). With ``fill=False`` they are absent from ``R_world_segment``.

Body proportions (:attr:`MappedMotion.body_dims`, metres) come from the rest offsets: joint-
centre distances for the limbs (``upper_leg`` hip->knee, ``lower_leg`` knee->ankle,
``upper_arm`` shoulder->elbow, ``forearm`` elbow->wrist, ``hand`` wrist->farthest non-thumb
point), ``hip_width`` and ``shoulder_width`` between the left and right hip / shoulder joint
centres, ``ankle_height`` the ankle above the lowest point of the rest foot, ``hip_height`` =
ankle height + lower + upper leg (legs straight), ``shoulder_height`` and ``height`` from the hip
joints up the rest trunk to the shoulder joints and to the top of the head (the head's End Site,
else its joint). ``foot_length`` is the ankle -> toe-tip distance along the rest foot's heading
divided by ``1 - HEEL_BEHIND_ANKLE``: a BVH foot has no heel point, and the model puts the heel
behind the ankle by that fraction of the foot length (so the model's own BVH maps back exactly).
Marker-based skeletons (CMU, SFU) put the toe End Site at the toe marker above the floor, so
their ``ankle_height`` is a few centimetres short.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache
from types import MappingProxyType
from typing import Literal

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..io.bvh import BvhMotion, BvhWorldPoses, Up, guess_bvh_scale, rotation_world_file
from ..model.layout import HEEL_BEHIND_ANKLE
from ..rotations import (
    exp_so3,
    log_so3,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
    slerp,
)

__all__ = [
    "MODEL_SEGMENTS",
    "SEGMENT_PARENTS",
    "SEGMENT_PROXIMAL_JOINTS",
    "MappedMotion",
    "SegmentSource",
    "SkeletonMap",
    "build_skeleton_map",
    "default_aliases",
    "map_motion",
    "normalize_joint_name",
]

#: The 23 model segments (SPEC section 2), parents before children.
MODEL_SEGMENTS: tuple[str, ...] = (
    "Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head",
    "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
    "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe",
)

#: Parent segment of each model segment (the Pelvis has none).
SEGMENT_PARENTS: Mapping[str, str | None] = {
    "Pelvis": None, "L5": "Pelvis", "L3": "L5", "T12": "L3", "T8": "T12", "Neck": "T8",
    "Head": "Neck",
    "RightShoulder": "T8", "RightUpperArm": "RightShoulder", "RightForeArm": "RightUpperArm",
    "RightHand": "RightForeArm",
    "LeftShoulder": "T8", "LeftUpperArm": "LeftShoulder", "LeftForeArm": "LeftUpperArm",
    "LeftHand": "LeftForeArm",
    "RightUpperLeg": "Pelvis", "RightLowerLeg": "RightUpperLeg", "RightFoot": "RightLowerLeg",
    "RightToe": "RightFoot",
    "LeftUpperLeg": "Pelvis", "LeftLowerLeg": "LeftUpperLeg", "LeftFoot": "LeftLowerLeg",
    "LeftToe": "LeftFoot",
}

#: The model joint (SPEC section 2) at each segment's proximal end; the Pelvis origin is the
#: midpoint of the hip joints (MVN's ``pHipOrigin``), given as ``MappedMotion.root_position``.
SEGMENT_PROXIMAL_JOINTS: Mapping[str, str] = {
    "L5": "jL5S1", "L3": "jL4L3", "T12": "jL1T12", "T8": "jT9T8", "Neck": "jT1C7",
    "Head": "jC1Head",
    "RightShoulder": "jRightT4Shoulder", "RightUpperArm": "jRightShoulder",
    "RightForeArm": "jRightElbow", "RightHand": "jRightWrist",
    "LeftShoulder": "jLeftT4Shoulder", "LeftUpperArm": "jLeftShoulder",
    "LeftForeArm": "jLeftElbow", "LeftHand": "jLeftWrist",
    "RightUpperLeg": "jRightHip", "RightLowerLeg": "jRightKnee", "RightFoot": "jRightAnkle",
    "RightToe": "jRightBallFoot",
    "LeftUpperLeg": "jLeftHip", "LeftLowerLeg": "jLeftKnee", "LeftFoot": "jLeftAnkle",
    "LeftToe": "jLeftBallFoot",
}

_TRUNK = ("Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head")
_EPS_LENGTH = 1e-9  # [file units] offsets shorter than this are "at the same place"

#: Alias templates per role; ``{Left}`` -> Left/Right, ``{L}`` -> L/R. Matching is done on
#: normalised names (:func:`normalize_joint_name`).
_ALIAS_TEMPLATES: Mapping[str, tuple[str, ...]] = {
    "Pelvis": ("Hips", "Pelvis", "Hip", "Bip01 Pelvis", "Bip001 Pelvis", "Root_Hips"),
    "Head": ("Head", "Bip01 Head", "Bip001 Head", "Head_JNT", "HeadJoint"),
    "Neck": ("Neck", "Neck1", "LowerNeck", "Bip01 Neck", "Bip001 Neck", "Neck_01"),
    "UpperLeg": (
        "{Left}UpLeg", "{Left}UpperLeg", "{Left}Thigh", "{L}Thigh", "{Left}Hip", "{Left}Femur",
        "{L}Femur", "{L}UpLeg", "UpperLeg_{L}", "Thigh_{L}", "UpLeg_{L}", "{L}_Thigh",
        "{L}_UpLeg", "{L}Hip", "Hip_{L}", "Bip01 {L} Thigh", "Bip001 {L} Thigh", "thigh_{L}",
    ),
    "LowerLeg": (
        "{Left}Leg", "{Left}Knee", "{Left}LowerLeg", "{Left}LowLeg", "{Left}Shin",
        "{Left}Calf", "{Left}Tibia", "{L}Tibia", "{L}Calf", "{L}Shin", "{L}Knee", "{L}Leg",
        "LowerLeg_{L}", "Shin_{L}", "Calf_{L}", "Knee_{L}", "Leg_{L}", "{L}_Calf", "{L}_Knee",
        "Bip01 {L} Calf", "Bip001 {L} Calf", "calf_{L}",
    ),
    "Foot": (
        "{Left}Foot", "{Left}Ankle", "{L}Foot", "{L}Ankle", "Foot_{L}", "Ankle_{L}",
        "{L}_Foot", "{L}_Ankle", "Bip01 {L} Foot", "Bip001 {L} Foot", "foot_{L}",
    ),
    "Toe": (
        "{Left}ToeBase", "{Left}Toe", "{Left}Toes", "{Left}Toe0", "{Left}Ball", "{L}Toe",
        "{L}Toes", "{L}ToeBase", "Toe_{L}", "Toes_{L}", "ToeBase_{L}", "Ball_{L}", "{L}_Toe",
        "Bip01 {L} Toe0", "Bip001 {L} Toe0", "ball_{L}",
    ),
    "UpperArm": (
        "{Left}Arm", "{Left}UpperArm", "{Left}UpArm", "{Left}Shoulder", "{L}Humerus",
        "{L}UpperArm", "{L}Arm", "{L}Shoulder", "UpperArm_{L}", "Arm_{L}", "Shoulder_{L}",
        "{L}_UpperArm", "{L}_Arm", "Bip01 {L} UpperArm", "Bip001 {L} UpperArm",
        "upperarm_{L}",
    ),
    "ForeArm": (
        "{Left}ForeArm", "{Left}Elbow", "{Left}LowerArm", "{Left}LowArm", "{L}ForeArm",
        "{L}Elbow", "{L}Radius", "{L}LowerArm", "ForeArm_{L}", "LowerArm_{L}", "Elbow_{L}",
        "{L}_ForeArm", "{L}_Elbow", "Bip01 {L} Forearm", "Bip001 {L} Forearm",
        "lowerarm_{L}",
    ),
    "Hand": (
        "{Left}Hand", "{Left}Wrist", "{L}Hand", "{L}Wrist", "Hand_{L}", "Wrist_{L}",
        "{L}_Hand", "{L}_Wrist", "Bip01 {L} Hand", "Bip001 {L} Hand", "hand_{L}",
    ),
}


def normalize_joint_name(name: str) -> str:
    """Joint name for matching: no prefix, lower case, letters and digits only.

    The part before the last ``:`` or ``|`` (a namespace or a path) is dropped:
    ``"mixamorig:Left_Up-Leg"`` -> ``"leftupleg"``.
    """
    base = name.replace("|", ":").rsplit(":", 1)[-1]
    return "".join(c for c in base.lower() if c.isalnum())


def default_aliases() -> dict[str, tuple[str, ...]]:
    """Normalised joint-name aliases per role, a table of its own on each call.

    Roles: ``Pelvis``, ``Head``, ``Neck`` and, for each side, ``<Side>UpperLeg``,
    ``<Side>LowerLeg``, ``<Side>Foot``, ``<Side>Toe``, ``<Side>UpperArm``, ``<Side>ForeArm``,
    ``<Side>Hand``. Pass an extended copy to :func:`build_skeleton_map` for other skeletons.
    """
    return dict(_default_alias_table())


@cache
def _default_alias_table() -> Mapping[str, tuple[str, ...]]:
    """:func:`default_aliases`, expanded from the templates once per process (read only)."""
    table: dict[str, tuple[str, ...]] = {}
    for role, templates in _ALIAS_TEMPLATES.items():
        if "{" not in "".join(templates):
            table[role] = tuple(dict.fromkeys(normalize_joint_name(t) for t in templates))
            continue
        for side, short in (("Left", "L"), ("Right", "R")):
            names = (t.replace("{Left}", side).replace("{L}", short) for t in templates)
            table[f"{side}{role}"] = tuple(dict.fromkeys(normalize_joint_name(n) for n in names))
    return MappingProxyType(table)


@dataclass(frozen=True, eq=False)
class SegmentSource:
    """Where one model segment comes from in the BVH.

    Attributes:
        segment: Model segment name.
        position_joint: BVH joint at the segment's proximal joint.
        orientation_joint: BVH joint whose rotation the segment follows.
        R_joint_segment: Constant rotation from the segment frame to that joint's frame.
    """

    segment: str
    position_joint: int
    orientation_joint: int
    R_joint_segment: np.ndarray


@dataclass(frozen=True, eq=False)
class SkeletonMap:
    """The per-skeleton part of the mapping, from :func:`build_skeleton_map`.

    Attributes:
        joint_names: The BVH joint names.
        scale: Metres per file unit [m].
        up: The file's up axis.
        sources: Mapped segments.
        missing: Model segments the BVH does not drive, in model order.
        hip_joints: BVH joints at the left and right hip (for the Pelvis origin).
        body_dims: Body proportions [m] with the keys of SPEC body files.
        R_world_body_rest: The body frame of the rest pose in our world.
        foot_level: Per foot / toe segment, the angle [rad] between the frame levelled on the
            clip's stance phases and the rest-pose frame (see the module notes, step 3).
            Absent where the clip has no steps to learn it from.
    """

    joint_names: tuple[str, ...]
    scale: float
    up: Up
    sources: dict[str, SegmentSource]
    missing: tuple[str, ...]
    hip_joints: tuple[int, int]
    body_dims: dict[str, float]
    R_world_body_rest: np.ndarray
    foot_level: dict[str, float] = field(default_factory=dict)

    def describe(self) -> dict[str, str]:
        """Segment -> BVH joint it follows (``"<position> / <orientation>"`` when they differ)."""
        out = {}
        for name, src in self.sources.items():
            pos = self.joint_names[src.position_joint]
            ori = self.joint_names[src.orientation_joint]
            out[name] = pos if pos == ori else f"{pos} / {ori}"
        return out


@dataclass(frozen=True, eq=False)
class MappedMotion:
    """A BVH motion expressed on the model segments, in our Z-up world.

    Attributes:
        time: Frame times [s], shape (F,).
        R_world_segment: Segment orientations in the MVN convention, each (F, 3, 3).
        p_world_joint: Positions of the mapped model joints (``jLeftKnee`` ...), each (F, 3) [m].
        root_position: Pelvis origin (midpoint of the hip joints), shape (F, 3) [m].
        body_dims: Body proportions [m] (SPEC section 2 body-file keys).
        missing: Segments the BVH lacks (interpolated or copied in ``R_world_segment`` when
            ``fill`` was on, absent otherwise).
        segment_joint: Segment -> BVH joint(s) it follows, for reports.
    """

    time: np.ndarray
    R_world_segment: dict[str, np.ndarray]
    p_world_joint: dict[str, np.ndarray]
    root_position: np.ndarray
    body_dims: dict[str, float]
    missing: tuple[str, ...]
    segment_joint: dict[str, str] = field(default_factory=dict)


# --------------------------------------------------------------------------- public API
def build_skeleton_map(
    motion: BvhMotion,
    *,
    scale: float | None = None,
    up: Up | Literal["auto"] = "auto",
    aliases: Mapping[str, tuple[str, ...]] | None = None,
    level_feet: bool = True,
) -> SkeletonMap:
    """Identify the model segments in a BVH skeleton and compute their rest offsets.

    Args:
        motion: The BVH file.
        scale: Metres per file unit [m]; guessed from the skeleton size when None
            (:func:`ikfusion.io.bvh.guess_bvh_scale`).
        up: The file's up axis, or ``"auto"``: the file axis (+Y or +Z) along which the rest
            skeleton stands (feet to head).
        aliases: Role -> normalised joint names (see :func:`default_aliases`).
        level_feet: Learn the feet's and toes' pitch from the clip's stance phases (see the
            module notes, step 3); off, the rest pose's feet are taken as level.

    Returns:
        The mapping, reusable for every frame of this skeleton.

    Raises:
        InputError: The pelvis, both legs (upper and lower) or the trunk/head cannot be
            found; the message lists the joint names present.
    """
    return _skeleton_map(motion, scale, up, aliases, level_feet, motion.world_poses)


#: ``BvhMotion.world_poses`` or what stands for it: (scale [m], up axis, frames) -> poses.
PosesAt = Callable[[float, Up, np.ndarray], BvhWorldPoses]


def _skeleton_map(motion: BvhMotion, scale: float | None, up: Up | Literal["auto"],
                  aliases: Mapping[str, tuple[str, ...]] | None, level_feet: bool,
                  poses_at: PosesAt) -> SkeletonMap:
    """:func:`build_skeleton_map`, the stance poses of ``level_feet`` from ``poses_at``."""
    table = _default_alias_table() if aliases is None else {
        k: tuple(normalize_joint_name(a) for a in v) for k, v in aliases.items()
    }
    tree = _Tree(motion)
    found = _identify(tree, table)
    _require(found, motion)
    unit = guess_bvh_scale(motion) if scale is None else float(scale)
    if not (np.isfinite(unit) and unit > 0.0):
        raise ValueError(f"scale must be a positive number of metres per unit, got {scale}")
    file_up = _detect_up(tree, found, motion) if up == "auto" else up
    A = rotation_world_file(file_up)
    rest_world = tree.rest @ A.T * unit
    end_world = tree.rest_end @ A.T * unit

    hip_l, hip_r = found.position["LeftUpperLeg"], found.position["RightUpperLeg"]
    R_world_body = _body_frame(rest_world[hip_l] - rest_world[hip_r], motion)
    sources: dict[str, SegmentSource] = {}
    directions: dict[str, np.ndarray] = {}
    for segment in MODEL_SEGMENTS:
        if segment not in found.position:
            continue
        orientation = found.orientation[segment]
        target = _rest_direction(tree, found, segment, rest_world, end_world)
        parent = SEGMENT_PARENTS[segment]
        if not target.any() and segment.endswith("Toe") and parent in directions:
            target = directions[parent]  # no toe tip (CMU): the toes continue the foot
        directions[segment] = target
        R_body_segment = _rest_correction(segment, R_world_body.T @ target)
        R_joint_segment = A.T @ R_world_body @ R_body_segment
        sources[segment] = SegmentSource(
            segment, found.position[segment], orientation, R_joint_segment
        )
    missing = tuple(s for s in MODEL_SEGMENTS if s not in sources)
    dims = _body_dims(tree, found, rest_world, end_world, R_world_body[:, 2])
    level: dict[str, float] = {}
    if level_feet:
        learnt = _level_feet(motion, unit, file_up, sources, directions, poses_at)
        for segment, R_new in learnt.items():
            src = sources[segment]
            level[segment] = float(np.linalg.norm(log_so3(src.R_joint_segment.T @ R_new)))
            sources[segment] = SegmentSource(
                segment, src.position_joint, src.orientation_joint, R_new
            )
    return SkeletonMap(
        joint_names=motion.joint_names,
        scale=unit,
        up=file_up,
        sources=sources,
        missing=missing,
        hip_joints=(hip_l, hip_r),
        body_dims=dims,
        R_world_body_rest=R_world_body,
        foot_level=level,
    )


def map_motion(
    motion: BvhMotion,
    *,
    scale: float | None = None,
    up: Up | Literal["auto"] = "auto",
    frames: npt.ArrayLike | slice | None = None,
    fill: bool = True,
    aliases: Mapping[str, tuple[str, ...]] | None = None,
    skeleton_map: SkeletonMap | None = None,
) -> MappedMotion:
    """Model segment orientations and joint positions of a BVH motion, frame by frame.

    Args:
        motion: The BVH file.
        scale: Metres per file unit [m]; guessed when None.
        up: The file's up axis or ``"auto"`` (see :func:`build_skeleton_map`).
        frames: Frames to map (index array or slice); all when None.
        fill: Give missing segments an interpolated / copied orientation (see module notes).
        aliases: Joint-name aliases per role (see :func:`default_aliases`).
        skeleton_map: A map built before for this skeleton (then ``scale``, ``up`` and
            ``aliases`` are not used).

    Returns:
        The motion on the model segments, in our Z-up world.
    """
    if skeleton_map is None:  # the map's stance poses and ours from one pass over the clip
        shared = _PosesOnce(motion, _frame_indices(motion, frames))
        smap = _skeleton_map(motion, scale, up, aliases, True, shared)
        poses = shared(smap.scale, smap.up, shared.later)
    else:
        smap = skeleton_map
        poses = motion.world_poses(smap.scale, smap.up, frames)
    R_world_joint = poses.R_world_joint
    p_world = poses.p_world_joint
    R_seg: dict[str, np.ndarray] = {}
    joints: dict[str, np.ndarray] = {}
    for segment, src in smap.sources.items():
        R_seg[segment] = R_world_joint[:, src.orientation_joint] @ src.R_joint_segment
        if segment in SEGMENT_PROXIMAL_JOINTS:
            joints[SEGMENT_PROXIMAL_JOINTS[segment]] = p_world[:, src.position_joint].copy()
    if fill:
        _fill_missing(R_seg, p_world.shape[0])
    ordered = {s: R_seg[s] for s in MODEL_SEGMENTS if s in R_seg}
    hip_l, hip_r = smap.hip_joints
    root = 0.5 * (p_world[:, hip_l] + p_world[:, hip_r])
    if frames is None:
        time = motion.times
    elif isinstance(frames, slice):
        time = motion.times[frames]
    else:
        time = motion.times[np.asarray(frames, dtype=int).reshape(-1)]
    return MappedMotion(
        time=time,
        R_world_segment=ordered,
        p_world_joint=joints,
        root_position=root,
        body_dims=dict(smap.body_dims),
        missing=smap.missing,
        segment_joint=smap.describe(),
    )


# --------------------------------------------------------------------------- the tree
class _Tree:
    """Parent/child queries and rest geometry of a BVH skeleton (file units and axes)."""

    def __init__(self, motion: BvhMotion) -> None:
        self.names = motion.joint_names
        self.norm = [normalize_joint_name(n) for n in motion.joint_names]
        self.parents = motion.parents
        self.offsets = motion.offsets
        self.rest, self.rest_end = motion.rest_positions()
        self.end_parents = motion.end_site_parents
        self.children = [
            [int(k) for k in np.flatnonzero(self.parents == j)] for j in range(len(self.names))
        ]
        depth = np.zeros(len(self.names), dtype=int)
        for j in range(1, len(self.names)):
            depth[j] = depth[self.parents[j]] + 1 if self.parents[j] >= 0 else 0
        self.depth = depth

    def ancestors(self, j: int) -> list[int]:
        """Strict ancestors of ``j``, nearest first."""
        out = []
        p = int(self.parents[j])
        while p >= 0:
            out.append(p)
            p = int(self.parents[p])
        return out

    def is_ancestor(self, a: int, j: int) -> bool:
        """True when ``a`` is a strict ancestor of ``j``."""
        return a in self.ancestors(j)

    def path(self, a: int, b: int) -> list[int]:
        """Joints strictly between ancestor ``a`` and descendant ``b``, top down."""
        chain = []
        p = int(self.parents[b])
        while p >= 0 and p != a:
            chain.append(p)
            p = int(self.parents[p])
        if p != a:
            raise ValueError(f"{self.names[a]} is not an ancestor of {self.names[b]}")
        return chain[::-1]

    def lca(self, a: int, b: int) -> int:
        """Lowest common ancestor (a joint is its own ancestor here)."""
        up_a = [a, *self.ancestors(a)]
        up_b = {b, *self.ancestors(b)}
        return next(j for j in up_a if j in up_b)

    def is_thumb(self, j: int) -> bool:
        """A thumb joint (excluded from hand directions)."""
        return "thumb" in self.norm[j]

    def merged(self, j: int) -> int:
        """Deepest joint reached through single, zero-offset, non-thumb children."""
        while True:
            kids = [k for k in self.children[j] if not self.is_thumb(k)]
            if len(kids) == 1 and np.linalg.norm(self.offsets[kids[0]]) < _EPS_LENGTH:
                j = int(kids[0])
            else:
                return j

    def single_child(self, j: int) -> int | None:
        """The only non-thumb child joint, if there is exactly one."""
        kids = [k for k in self.children[j] if not self.is_thumb(k)]
        return int(kids[0]) if len(kids) == 1 else None

    def matches(self, names: tuple[str, ...]) -> list[int]:
        """Joints whose normalised name is one of ``names``, shallowest first."""
        wanted = set(names)
        hits = [j for j, n in enumerate(self.norm) if n in wanted]
        return sorted(hits, key=lambda j: (self.depth[j], j))


@dataclass
class _Found:
    """Joint indices per segment, plus the chain points used for directions."""

    position: dict[str, int] = field(default_factory=dict)
    orientation: dict[str, int] = field(default_factory=dict)
    distal: dict[str, list[int]] = field(default_factory=dict)  # later anchors on the chain
    head: int | None = None


def _identify(tree: _Tree, table: Mapping[str, tuple[str, ...]]) -> _Found:
    found = _Found()
    for side in ("Left", "Right"):
        _identify_leg(tree, table, side, found)
        _identify_arm(tree, table, side, found)
    _identify_pelvis(tree, table, found)
    if "Pelvis" in found.position:
        _identify_trunk(tree, table, found)
    return found


def _first_below(tree: _Tree, candidates: list[int], top: int) -> int | None:
    return next((c for c in candidates if tree.is_ancestor(top, c)), None)


def _limb(tree: _Tree, table: Mapping[str, tuple[str, ...]], upper: str, middle: str,
          end: str) -> tuple[int, int, int | None] | None:
    """The top, middle and end joints of a limb (hip, knee, ankle; shoulder, elbow, wrist).

    Matched by the names ``table`` gives the segments ``upper``, ``middle`` and ``end``: the
    middle joint is the first match with an end joint below it (else the first match), the top
    joint the deepest match above it (else its parent), the end joint the first match below it
    (else its only child). None when no middle joint below the root is found.
    """
    middles = tree.matches(table.get(middle, ()))
    ends = tree.matches(table.get(end, ()))
    mid = next((k for k in middles if _first_below(tree, ends, k) is not None),
               middles[0] if middles else None)
    if mid is None or tree.parents[mid] < 0:
        return None
    above = [a for a in tree.matches(table.get(upper, ())) if tree.is_ancestor(a, mid)]
    top = max(above, key=lambda a: tree.depth[a]) if above else int(tree.parents[mid])
    tip = _first_below(tree, ends, mid)
    if tip is None:
        tip = tree.single_child(tree.merged(mid))
    return top, mid, tip


def _identify_leg(tree: _Tree, table: Mapping[str, tuple[str, ...]], side: str,
                  found: _Found) -> None:
    limb = _limb(tree, table, f"{side}UpperLeg", f"{side}LowerLeg", f"{side}Foot")
    if limb is None:
        return
    hip, knee, foot = limb
    toe = None
    if foot is not None:
        toe = _first_below(tree, tree.matches(table.get(f"{side}Toe", ())), foot)
        if toe is None:
            toe = tree.single_child(tree.merged(foot))
    chain = [(f"{side}UpperLeg", hip), (f"{side}LowerLeg", knee), (f"{side}Foot", foot),
             (f"{side}Toe", toe)]
    _set_chain(tree, found, chain)


def _identify_arm(tree: _Tree, table: Mapping[str, tuple[str, ...]], side: str,
                  found: _Found) -> None:
    limb = _limb(tree, table, f"{side}UpperArm", f"{side}ForeArm", f"{side}Hand")
    if limb is None:
        return
    shoulder, elbow, hand = limb
    chain = [(f"{side}UpperArm", shoulder), (f"{side}ForeArm", elbow), (f"{side}Hand", hand)]
    _set_chain(tree, found, chain)


def _set_chain(tree: _Tree, found: _Found, chain: list[tuple[str, int | None]]) -> None:
    """Positions, orientation joints and distal anchors of a proximal-to-distal chain."""
    present = [(s, j) for s, j in chain if j is not None]
    for i, (segment, joint) in enumerate(present):
        found.position[segment] = int(joint)
        later = [int(j) for _, j in present[i + 1:]]
        found.distal[segment] = later
        found.orientation[segment] = (
            int(tree.parents[later[0]]) if later else tree.merged(int(joint))
        )


def _identify_pelvis(tree: _Tree, table: Mapping[str, tuple[str, ...]], found: _Found) -> None:
    hips = [found.position.get(f"{s}UpperLeg") for s in ("Left", "Right")]
    if hips[0] is None or hips[1] is None:
        return
    hip_l, hip_r = int(hips[0]), int(hips[1])
    common = tree.lca(hip_l, hip_r)
    if common in (hip_l, hip_r):
        return
    named = [j for j in tree.matches(table.get("Pelvis", ()))
             if j == common or tree.is_ancestor(j, common)]
    pelvis = max(named, key=lambda j: tree.depth[j]) if named else common
    found.position["Pelvis"] = pelvis
    found.orientation["Pelvis"] = pelvis
    found.distal["Pelvis"] = []


def _identify_trunk(tree: _Tree, table: Mapping[str, tuple[str, ...]], found: _Found) -> None:
    pelvis = found.position["Pelvis"]
    shoulders = [found.position.get(f"{s}UpperArm") for s in ("Left", "Right")]
    heads = [h for h in tree.matches(table.get("Head", ())) if tree.is_ancestor(pelvis, h)]
    head = heads[0] if heads else None
    thorax: int | None = None
    arms = [int(s) for s in shoulders if s is not None and tree.is_ancestor(pelvis, s)]
    if len(arms) == 2:
        thorax = tree.lca(arms[0], arms[1])
    elif len(arms) == 1 and head is not None:
        thorax = tree.lca(arms[0], head)
    elif head is not None:
        necks = [n for n in tree.matches(table.get("Neck", ()))
                 if tree.is_ancestor(n, head) and tree.is_ancestor(pelvis, n)]
        if necks and tree.parents[necks[0]] != pelvis:
            thorax = int(tree.parents[necks[0]])
    if thorax is not None and (thorax == pelvis or not tree.is_ancestor(pelvis, thorax)):
        thorax = None
    if head is not None and thorax is not None and not tree.is_ancestor(thorax, head):
        head = None
    found.head = head

    # Lumbar joints: between the pelvis and T8, dropping zero-length bones.
    top = thorax if thorax is not None else head
    lumbar: list[int] = []
    if top is not None:
        path = tree.path(pelvis, top)
        nxt = [*path[1:], top]
        lumbar = [j for j, n in zip(path, nxt)
                  if np.linalg.norm(tree.rest[n] - tree.rest[j]) >= _EPS_LENGTH]
        if thorax is None:
            lumbar = []  # without T8 the spine cannot be split into lumbar and thoracic parts
    if len(lumbar) == 1:
        names = ["L5"]
    elif len(lumbar) == 2:
        names = ["L5", "T12"]
    else:
        names = ["L5", "L3", "T12"]
        if len(lumbar) > 3:
            lumbar = [lumbar[0], lumbar[len(lumbar) // 2], lumbar[-1]]
    neck_path = tree.path(thorax, head) if (thorax is not None and head is not None) else []
    neck = neck_path[0] if neck_path else None

    trunk: list[tuple[str, int | None]] = [(s, j) for s, j in zip(names, lumbar)]
    trunk += [("T8", thorax), ("Neck", neck), ("Head", head)]
    _set_chain(tree, found, trunk)
    # Clavicles: the joints between T8 and an upper arm.
    for side in ("Left", "Right"):
        upper = found.position.get(f"{side}UpperArm")
        if thorax is None or upper is None or not tree.is_ancestor(thorax, upper):
            continue
        between = tree.path(thorax, upper)
        if between:
            found.position[f"{side}Shoulder"] = between[0]
            found.orientation[f"{side}Shoulder"] = int(tree.parents[upper])
            found.distal[f"{side}Shoulder"] = [upper, *found.distal.get(f"{side}UpperArm", [])]


def _require(found: _Found, motion: BvhMotion) -> None:
    needed = ["Pelvis", "LeftUpperLeg", "RightUpperLeg", "LeftLowerLeg", "RightLowerLeg"]
    lacking = [s for s in needed if s not in found.position]
    if "T8" not in found.position and "Head" not in found.position:
        lacking.append("T8 or Head (trunk)")
    if lacking:
        raise InputError(
            f"cannot map this BVH skeleton onto the model: no joint found for "
            f"{', '.join(lacking)}. Joint names in the file: {', '.join(motion.joint_names)}. "
            "Pass aliases= with these names (see ikfusion.mocap.skeleton_map.default_aliases).",
            motion.path, field="HIERARCHY",
        )


def _detect_up(tree: _Tree, found: _Found, motion: BvhMotion) -> Up:
    top = found.head if found.head is not None else found.position.get("T8")
    feet = [found.position[f"{s}LowerLeg"] for s in ("Left", "Right")]
    if top is None:  # pragma: no cover - _require guarantees T8 or Head
        raise InputError("no trunk joint to find the up axis", motion.path)
    d = tree.rest[top] - 0.5 * (tree.rest[feet[0]] + tree.rest[feet[1]])
    axis = int(np.argmax(np.abs(d)))
    if axis == 1 and d[1] > 0:
        return "y"
    if axis == 2 and d[2] > 0:
        return "z"
    raise InputError(
        f"the rest skeleton stands along {'-' if d[axis] < 0 else '+'}{'XYZ'[axis]} (feet to "
        "head), not +Y or +Z; pass up='y' or up='z'", motion.path, field="OFFSET",
    )


# --------------------------------------------------------------------------- geometry
def _body_frame(left_vector: np.ndarray, motion: BvhMotion) -> np.ndarray:
    """``R_world_body`` of the rest pose: Z up, Y from the right to the left hip, X = Y x Z."""
    up = np.array([0.0, 0.0, 1.0])
    left = left_vector - up * (left_vector @ up)
    norm = np.linalg.norm(left)
    if norm < 1e-9:
        raise InputError(
            "the left and right hip joints are at the same horizontal place in the rest pose; "
            "cannot find the body's facing direction", motion.path, field="OFFSET",
        )
    left = left / norm
    forward = np.cross(left, up)
    return np.column_stack([forward, left, up])


def _rest_direction(
    tree: _Tree, found: _Found, segment: str, rest_world: np.ndarray, end_world: np.ndarray
) -> np.ndarray:
    """Unit rest direction (world axes) from the segment's orientation joint to its distal end.

    The first later anchor of the chain that is not at the same place, else the farthest
    non-thumb point (joint or End Site) below the orientation joint; zero when there is none.
    """
    joint = found.orientation[segment]
    origin = rest_world[joint]
    for anchor in found.distal.get(segment, []):
        d = rest_world[anchor] - origin
        if np.linalg.norm(d) > _EPS_LENGTH:
            return d / np.linalg.norm(d)
    points = _points_below(tree, joint, rest_world, end_world) - origin
    if points.size == 0:
        return np.zeros(3)
    lengths = np.linalg.norm(points, axis=1)
    k = int(np.argmax(lengths))
    return points[k] / lengths[k] if lengths[k] > _EPS_LENGTH else np.zeros(3)


def _rest_correction(segment: str, direction_body: np.ndarray) -> np.ndarray:
    """``R_body_segment`` in the rest pose (see the module notes, step 3)."""
    norm = np.linalg.norm(direction_body)
    if norm < 1e-12:
        return np.eye(3)
    d = direction_body / norm
    if segment.endswith(("UpperLeg", "LowerLeg", "UpperArm", "ForeArm", "Hand")):
        return _align(np.array([0.0, 0.0, -1.0]), d)
    if segment.endswith(("Foot", "Toe")):
        if np.hypot(d[0], d[1]) < 1e-6:
            return np.eye(3)
        return exp_so3(np.array([0.0, 0.0, np.arctan2(d[1], d[0])]))
    return np.eye(3)


def _align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit ``a`` onto unit ``b`` (about body X when opposite)."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    c = float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        return exp_so3(np.array([np.pi, 0.0, 0.0]))
    return exp_so3(axis / s * np.arctan2(s, c))


def _frame_indices(motion: BvhMotion, frames: npt.ArrayLike | slice | None) -> np.ndarray:
    """The frame indices that ``frames`` (None: all, a slice or indices) selects."""
    if frames is None or isinstance(frames, slice):
        return np.arange(motion.num_frames)[frames if frames is not None else slice(None)]
    return np.asarray(frames, dtype=int).reshape(-1)


class _PosesOnce:
    """``BvhMotion.world_poses`` for two passes over one clip, computed once.

    The first call (the skeleton map's stance frames) computes the poses at its frames and at
    ``later`` (the frames :func:`map_motion` maps) together; a call with the same scale and up
    axis at frames among those takes its rows from them. Each frame's forward kinematics is
    its own, so the rows are those a call at only these frames gives, to the bit.

    Attributes:
        later: Frame indices a later call will ask for.
    """

    def __init__(self, motion: BvhMotion, later: np.ndarray) -> None:
        self.motion = motion
        self.later = later
        self._key: tuple[float, Up] | None = None
        self._frames = np.zeros(0, dtype=int)
        self._poses: BvhWorldPoses | None = None

    def __call__(self, scale: float, up: Up, frames: np.ndarray) -> BvhWorldPoses:
        """World poses at ``frames`` (indices), as ``motion.world_poses(scale, up, frames)``."""
        if self._poses is None or self._key != (scale, up):
            self._key = (scale, up)
            self._frames = np.union1d(frames, self.later)
            self._poses = self.motion.world_poses(scale, up, self._frames)
        elif not np.isin(frames, self._frames).all():  # pragma: no cover - not asked for
            return self.motion.world_poses(scale, up, frames)
        rows = np.searchsorted(self._frames, frames)
        return BvhWorldPoses(*(a[rows] for a in self._poses))


def _level_feet(
    motion: BvhMotion,
    scale: float,
    up: Up,
    sources: dict[str, SegmentSource],
    directions: dict[str, np.ndarray],
    poses_at: PosesAt,
) -> dict[str, np.ndarray]:
    """Foot and toe frames that are level while standing flat, learnt from the clip.

    Stance is found on a ~30 Hz subsample of the clip: the ankle and the toe joint both within
    3 cm of their low level (2nd percentile of their height) and the ankle moving slower than
    0.2 m/s horizontally. A foot is
    only levelled when the clip has steps (between its 5th and 95th percentiles the ankle rises
    by more than 5 cm or travels more than 0.5 m) and at least 5 stance samples. The segment
    frame is then rebuilt in the BVH joint's frame: Z = the mean world up seen from the joint
    during stance, X = the rest direction to the segment's distal end (ankle -> toe joint,
    toe joint -> toe tip) made perpendicular to Z, Y = Z x X.

    Returns:
        Segment -> new ``R_joint_segment``.

    Args:
        motion: The clip.
        scale: Metres per file unit [m].
        up: The file's up axis.
        sources: The segments mapped so far.
        directions: Unit rest direction to each segment's distal end, world axes.
        poses_at: The clip's world poses (``motion.world_poses`` or one shared with others).
    """
    n = motion.num_frames
    if n < 10:
        return {}
    step = max(1, int(round(motion.frame_rate / 30.0)))
    frames = np.arange(0, n, step)
    poses = poses_at(scale, up, frames)
    times = frames * motion.frame_time
    R_file_world = rotation_world_file(up).T
    out: dict[str, np.ndarray] = {}
    for side in ("Left", "Right"):
        foot, toe = f"{side}Foot", f"{side}Toe"
        if foot not in sources or toe not in sources:
            continue
        ankle = poses.p_world_joint[:, sources[foot].position_joint]
        ball = poses.p_world_joint[:, sources[toe].position_joint]
        good = np.all(np.isfinite(ankle), axis=1) & np.all(np.isfinite(ball), axis=1)
        if good.sum() < 10:
            continue
        ankle, ball, t = ankle[good], ball[good], times[good]
        low, high = np.percentile(ankle, [5.0, 95.0], axis=0)
        if high[2] - low[2] < 0.05 and np.linalg.norm(high[:2] - low[:2]) < 0.5:
            continue
        speed = np.linalg.norm(np.gradient(ankle[:, :2], t, axis=0), axis=1)
        stance = ((ankle[:, 2] < np.percentile(ankle[:, 2], 2.0) + 0.03)
                  & (ball[:, 2] < np.percentile(ball[:, 2], 2.0) + 0.03) & (speed < 0.2))
        if stance.sum() < 5:
            continue
        for segment in (foot, toe):
            src = sources[segment]
            R = poses.R_world_joint[:, src.orientation_joint][good][stance]
            z = R[:, 2, :].mean(axis=0)  # world up in the joint frame (rows of R^T e_z)
            z /= np.linalg.norm(z)
            # Distal direction in the joint frame: the rest joint frame is the file frame.
            x = R_file_world @ directions[segment]
            x = x - z * (x @ z)
            if np.linalg.norm(x) < 1e-6:
                continue
            x /= np.linalg.norm(x)
            out[segment] = np.column_stack([x, np.cross(z, x), z])
    return out


def _body_dims(
    tree: _Tree, found: _Found, rest: np.ndarray, rest_end: np.ndarray, up: np.ndarray
) -> dict[str, float]:
    """Body proportions [m] from the rest skeleton (see the module notes)."""
    pos = found.position

    def dist(a: str, b: str) -> float | None:
        if a in pos and b in pos:
            return float(np.linalg.norm(rest[pos[a]] - rest[pos[b]]))
        return None

    def both(a: str, b: str) -> float | None:
        vals = [dist(f"{s}{a}", f"{s}{b}") for s in ("Left", "Right")]
        vals_ok = [v for v in vals if v is not None]
        return float(np.mean(vals_ok)) if vals_ok else None

    dims: dict[str, float | None] = {
        "upper_leg": both("UpperLeg", "LowerLeg"),
        "lower_leg": both("LowerLeg", "Foot"),
        "upper_arm": both("UpperArm", "ForeArm"),
        "forearm": both("ForeArm", "Hand"),
        "hip_width": dist("LeftUpperLeg", "RightUpperLeg"),
        "shoulder_width": dist("LeftUpperArm", "RightUpperArm"),
    }
    hands, feet, ankles = [], [], []
    for side in ("Left", "Right"):
        hand = pos.get(f"{side}Hand")
        if hand is not None:
            points = _points_below(tree, hand, rest, rest_end)
            if points.size:
                hands.append(float(np.max(np.linalg.norm(points - rest[hand], axis=1))))
        foot = pos.get(f"{side}Foot")
        if foot is not None:
            points = _points_below(tree, foot, rest, rest_end)
            if points.size:
                rel = points - rest[foot]
                horizontal = rel - np.outer(rel @ up, up)
                feet.append(float(np.max(np.linalg.norm(horizontal, axis=1)))
                             / (1.0 - HEEL_BEHIND_ANKLE))
                ankles.append(float(-np.min(rel @ up)))
    dims["hand"] = float(np.mean(hands)) if hands and max(hands) > 0 else None
    dims["foot_length"] = float(np.mean(feet)) if feet and max(feet) > 0 else None
    ankle = float(np.mean(ankles)) if ankles else 0.0
    dims["ankle_height"] = ankle if ankles else None
    leg = (dims["upper_leg"] or 0.0) + (dims["lower_leg"] or 0.0)
    if dims["upper_leg"] is not None and dims["lower_leg"] is not None:
        hip_height = ankle + leg
        dims["hip_height"] = hip_height
        hip_mid = 0.5 * (rest[pos["LeftUpperLeg"]] + rest[pos["RightUpperLeg"]])
        shoulders = [rest[pos[f"{s}UpperArm"]] for s in ("Left", "Right")
                     if f"{s}UpperArm" in pos]
        if shoulders:
            dims["shoulder_height"] = hip_height + float((np.mean(shoulders, axis=0) - hip_mid)
                                                         @ up)
        if found.head is not None:
            head_points = _points_below(tree, found.head, rest, rest_end)
            top = max([float(rest[found.head] @ up)]
                      + [float(p @ up) for p in head_points])
            dims["height"] = hip_height + top - float(hip_mid @ up)
    return {k: float(v) for k, v in dims.items() if v is not None}


def _points_below(tree: _Tree, j: int, rest: np.ndarray, rest_end: np.ndarray) -> np.ndarray:
    """World rest points (joints and End Sites, no thumbs) below joint ``j``, shape (N, 3)."""
    out: list[np.ndarray] = []
    stack = [j]
    while stack:
        k = stack.pop()
        out.extend(rest_end[e] for e in np.flatnonzero(tree.end_parents == k))
        for c in tree.children[k]:
            if not tree.is_thumb(c):
                out.append(rest[c])
                stack.append(int(c))
    return np.array(out).reshape(-1, 3)


# --------------------------------------------------------------------------- filling
def _fill_missing(R_seg: dict[str, np.ndarray], n_frames: int) -> None:
    """Orientation for missing segments: trunk slerp between mapped neighbours, else copy."""
    for i, segment in enumerate(_TRUNK):
        if segment in R_seg:
            continue
        below = next((j for j in range(i - 1, -1, -1) if _TRUNK[j] in R_seg), None)
        above = next((j for j in range(i + 1, len(_TRUNK)) if _TRUNK[j] in R_seg), None)
        if below is not None and above is not None:
            t = (i - below) / (above - below)
            q0 = matrix_to_quat_wxyz(R_seg[_TRUNK[below]])
            q1 = matrix_to_quat_wxyz(R_seg[_TRUNK[above]])
            R_seg[segment] = quat_wxyz_to_matrix(slerp(q0, q1, t))
        elif below is not None:
            R_seg[segment] = R_seg[_TRUNK[below]].copy()
        elif above is not None:  # pragma: no cover - the Pelvis is always mapped
            R_seg[segment] = R_seg[_TRUNK[above]].copy()
    for segment in MODEL_SEGMENTS:
        if segment in R_seg:
            continue
        parent = SEGMENT_PARENTS[segment]
        while parent is not None and parent not in R_seg:  # pragma: no cover - order guarantees
            parent = SEGMENT_PARENTS[parent]
        R_seg[segment] = (R_seg[parent].copy() if parent is not None
                          else np.broadcast_to(np.eye(3), (n_frames, 3, 3)).copy())
